"""The full transition trace of a run (paper §6.1: every Coordinator's fully-qualified state), always
written to a file in the ROS log directory, whatever the console shows.

One line per state change of every composite, in the ``--verbose`` console format
(``[state] <composite>: <state>  <- <event>``), plus the SAFETY line, warnings and the summary.
"""

from __future__ import annotations

import datetime
import os
import pathlib
from typing import TextIO

__all__ = ['TraceFile']


class TraceFile:
    """``<ROS log dir>/bootstrap_<app>_<date>-<time>_<pid>.log``, line-buffered."""

    def __init__(self, *, app: str) -> None:
        from rclpy.logging import get_logging_directory

        stamp = datetime.datetime.now().strftime('%Y%m%d-%H%M%S')
        path = pathlib.Path(get_logging_directory()) / f'bootstrap_{app}_{stamp}_{os.getpid()}.log'
        self.path: pathlib.Path | None = path
        self._file: TextIO | None = None
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            self._file = open(path, 'w', buffering=1, encoding='utf-8')
        except OSError:  # a read-only log directory costs the trace, not the run
            self.path = None

    def write(self, line: str) -> None:
        if self._file is not None:
            self._file.write(line + '\n')

    def close(self) -> None:
        if self._file is not None:
            self._file.close()
            self._file = None
