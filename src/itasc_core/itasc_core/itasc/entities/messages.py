"""Data-flow messages of the constraint-based program's Functional Entities (paper §4.1, §7).

Between the Scene, the entities of a Task and the Solver flow vectors with a Jacobian (feature
coordinates chi_f, outputs y, setpoints with their velocity). They travel as a *labelled table*
in a standard ``std_msgs/Float64MultiArray``: a row-major (m x k) matrix whose layout names its
rows and columns, so that every message says what its numbers are::

    layout.dim[0].label = 'x,y,z,rx,ry,rz;rotation=3'   rows (size m); optional ';rotation=i':
                                                        rows i..i+2 are a log3 rotation triple
    layout.dim[1].label = 'value,panda_joint1,...'      columns (size k)

e.g. a VKC's features: column ``value`` holds chi_f, the other columns (named by joint) hold the
Jacobian on the program-wide joint velocities. Times in stamps are the program time ``t`` of the
Scheduler tick that produced the data, so a Solver can tell this tick's rows from stale ones.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from builtin_interfaces.msg import Time
from std_msgs.msg import Float64MultiArray, MultiArrayDimension

__all__ = ['Table', 'table_msg', 'read_table', 'stamp', 'seconds']


@dataclass(frozen=True)
class Table:
    """A decoded labelled table."""

    rows: tuple[str, ...]
    columns: tuple[str, ...]
    values: np.ndarray  # (len(rows), len(columns))
    rotation: int | None = None  # first row of a log3 rotation triple, if any

    def column(self, name: str) -> np.ndarray:
        return self.values[:, self.columns.index(name)]

    def matrix(self, first: int = 1) -> np.ndarray:
        """Columns from ``first`` on (e.g. the Jacobian after the ``value`` column)."""
        return self.values[:, first:]


def table_msg(rows: Sequence[str], columns: Sequence[str], values: np.ndarray, *,
              rotation: int | None = None) -> Float64MultiArray:
    """Encode a (len(rows) x len(columns)) matrix as a labelled ``Float64MultiArray``."""
    m, k = len(rows), len(columns)
    row_label = ','.join(rows) + (f';rotation={rotation}' if rotation is not None else '')
    msg = Float64MultiArray()
    msg.layout.dim = [MultiArrayDimension(label=row_label, size=m, stride=m * k),
                      MultiArrayDimension(label=','.join(columns), size=k, stride=k)]
    msg.data = np.asarray(values, dtype=float).reshape(m * k).tolist()
    return msg


@lru_cache(maxsize=256)
def _labels(row_label: str, column_label: str) -> tuple[tuple[str, ...], tuple[str, ...], int | None]:
    names, _, marker = row_label.partition(';rotation=')
    split = lambda text: tuple(text.split(',')) if text else ()  # noqa: E731
    return split(names), split(column_label), int(marker) if marker else None


def read_table(msg: Float64MultiArray) -> Table:
    """Decode a labelled table; raises ValueError if the layout does not match the data."""
    if len(msg.layout.dim) != 2:
        raise ValueError('a labelled table has exactly two layout dimensions')
    rows, columns, rotation = _labels(msg.layout.dim[0].label, msg.layout.dim[1].label)
    values = np.asarray(msg.data, dtype=float)
    if values.size != len(rows) * len(columns):
        raise ValueError(f'table of {len(rows)} x {len(columns)} labels carries {values.size} numbers')
    return Table(rows, columns, values.reshape(len(rows), len(columns)), rotation)


def stamp(t: float) -> Time:
    """The program time ``t`` (seconds) as a ROS time stamp."""
    sec = int(np.floor(t))
    return Time(sec=sec, nanosec=min(int(round((t - sec) * 1e9)), 999_999_999))


def seconds(time: Time) -> float:
    return time.sec + time.nanosec * 1e-9
