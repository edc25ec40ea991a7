"""The trigger of a composite in another process (paper §6.1, issue #9): its parent's Scheduler
sends one ``itasc_msgs/Trigger`` a tick, which carries the newest samples of the outputs in the
parent's process that the composite reads.

A child composite computes in the tick its parent triggers, from what the parent's entities wrote
in that tick (a Task's VKC reads the Scene's relation). As messages of their own, these samples
cost a DDS send and a wake-up of the child's process each, and came after the trigger now and then,
so that the child computed from the relation of the tick before. Carried in the trigger, they
arrive with it, and are handed to the child's inputs before its tick. Their topics stay observable:
the output still publishes a message whenever another DDS reader (``ros2 topic echo``, a recorder)
listens. Each sample travels as the CDR bytes a reader of its topic would take
(:mod:`.cdr`), so the child decodes it as it would decode that message.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from typing import Any

import numpy as np
from itasc_msgs.msg import Trigger

from .cdr import serialize
from .samples import Sample, sample_of

__all__ = ['TriggerSample', 'trigger_of']

_NONE = np.zeros(0, dtype=np.uint8)


@sample_of(Trigger)
class TriggerSample(Sample):
    """A tick ``t`` and the carried samples: ``topics``, the CDR size of each, their bytes in ``data``."""

    __slots__ = ('t', 'topics', 'sizes', 'data')

    def __init__(self, t: float, topics: Sequence[str] = (), sizes: Any = _NONE, data: Any = _NONE) -> None:
        self.t, self.topics, self.sizes, self.data = t, tuple(topics), sizes, data

    def carried(self) -> Iterator[tuple[str, bytes]]:
        """Each carried sample: its topic and CDR bytes."""
        start = 0
        data = self.data
        for topic, size in zip(self.topics, self.sizes.tolist()):
            yield topic, data[start:start + size].tobytes()
            start += size

    def to_message(self) -> Trigger:
        return Trigger(t=self.t, topics=list(self.topics), sizes=np.asarray(self.sizes, dtype=np.uint32),
                       data=np.asarray(self.data, dtype=np.uint8))

    @classmethod
    def from_message(cls, msg: Trigger) -> 'TriggerSample':
        return cls(msg.t, tuple(msg.topics), np.asarray(msg.sizes, dtype=np.uint32),
                   np.asarray(msg.data, dtype=np.uint8))


def trigger_of(t: float, samples: Sequence[tuple[str, Any]]) -> TriggerSample:
    """The trigger of tick ``t`` carrying ``samples`` ((topic, sample) pairs)."""
    if not samples:
        return TriggerSample(t)
    chunks = [serialize(sample) for _, sample in samples]
    return TriggerSample(t, [topic for topic, _ in samples], np.array([len(c) for c in chunks], dtype=np.uint32),
                         np.frombuffer(b''.join(chunks), dtype=np.uint8))
