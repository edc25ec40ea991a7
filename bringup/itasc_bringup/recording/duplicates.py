"""Each message once, when the recorder takes a topic through several readers (SPEC: "recording the
whole run"; paper §7.2: no event lost, and none invented either).

One reader cannot match every writer of a topic: a transient-local reader (needed to get the first
events a writer raised before the recorder matched it) does not match a volatile writer, a reliable
reader does not match a best-effort one. The recorder then adds a reader that does, and a writer
both match delivers each message to both. :class:`Duplicates` tells the copies apart by content
(the serialized bytes): a message is written as many times as the reader that saw it most often
saw it, so two equal messages published on purpose are both kept, and a message delivered to two
readers is kept once.
"""

from __future__ import annotations

from collections import OrderedDict

__all__ = ['Duplicates']


class Duplicates:
    """Which messages of one topic, taken by several readers, are new."""

    def __init__(self, *, window: int) -> None:
        #: serialized message -> [written, seen by reader 0, seen by reader 1, ...]
        self._seen: OrderedDict[bytes, list[int]] = OrderedDict()
        #: how many messages are remembered; a copy arriving later than ``window`` other messages
        #: after the first is written again
        self.window = window

    def new(self, data: bytes, *, reader: int) -> bool:
        """Whether ``data``, taken by reader number ``reader``, is to be written."""
        counts = self._seen.get(data)
        if counts is None:
            counts = self._seen[data] = [0]
            if len(self._seen) > self.window:
                self._seen.popitem(last=False)
        if len(counts) <= reader + 1:
            counts.extend([0] * (reader + 2 - len(counts)))
        counts[reader + 1] += 1
        if counts[reader + 1] <= counts[0]:
            return False
        counts[0] += 1
        return True
