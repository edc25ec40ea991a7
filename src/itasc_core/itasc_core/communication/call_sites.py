"""Where a log line comes from, found without stopping the caller (paper §7: log lines are part of
what an entity communicates, §6.2: its computation must keep its rate meanwhile).

rclpy (Jazzy) finds the call site of every log call, throttled or not, with ``inspect.getframeinfo``,
which reads the caller's source lines and resolves paths through every frame: 2.35 ms a throttled
call on a 2-core VM, and 43.6 ms for the first call of a process (``inspect`` then maps every loaded
module to its file; ``bench/bench_logging.py``). A Solver's first warning at 500 Hz held its
composite's ticks for 15-30 periods.
:func:`install` gives rclpy a ``CallerId`` that takes the same four values (function, absolute file,
line, bytecode offset) from the calling frame's code object; rclpy's filters (``throttle_duration_sec``,
``once``, ``skip_first``), which keep their state per call site, work as before.
"""

from __future__ import annotations

import os
import sys
from functools import lru_cache
from types import FrameType

import rclpy.logging
from rclpy.impl import rcutils_logger

__all__ = ['CallerId', 'install']

#: rclpy's own logging modules, whose frames are not the call site (as rclpy's ``_find_caller``)
_RCLPY_FILES = frozenset(os.path.realpath(path) for path in (rcutils_logger.__file__, rclpy.logging.__file__))


@lru_cache(maxsize=None)
def _file(filename: str) -> tuple[str, bool]:
    """``filename``'s absolute path, and whether it is one of rclpy's logging modules."""
    return os.path.abspath(filename), os.path.realpath(filename) in _RCLPY_FILES


class CallerId(rcutils_logger.CallerId):
    """rclpy's call site of a log call, from frame attributes only."""

    __slots__ = ()

    def __new__(cls, frame: FrameType | None = None) -> 'CallerId':
        if frame is None:
            frame = sys._getframe(1)
            while frame.f_back is not None and _file(frame.f_code.co_filename)[1]:
                frame = frame.f_back
        return tuple.__new__(cls, (frame.f_code.co_name, _file(frame.f_code.co_filename)[0], frame.f_lineno,
                                   frame.f_lasti))


def install() -> None:
    """Have rclpy's loggers of this process find their call sites with :class:`CallerId`."""
    rcutils_logger.CallerId = CallerId  # type: ignore[misc]
