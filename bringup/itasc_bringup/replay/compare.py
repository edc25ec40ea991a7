"""Comparing what a replay computed with what was recorded, tick by tick: the largest difference
per joint of a command, and per Task of its error and of its rows, with the tick it is at."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

__all__ = ['Largest', 'command_differences', 'task_difference']

Vector = np.ndarray | None  # None: nothing computed at that tick


@dataclass(frozen=True)
class Largest:
    """The largest difference of one quantity over all ticks (inf: computed on one side only)."""

    name: str
    value: float
    t: float | None = None
    #: what was recorded and what was replayed there, in words
    where: str = ''

    def line(self, what: str) -> str:
        at = f' at t={self.t:.3f} s ({self.where})' if self.t is not None else ''
        return f'  {self.name:24s} largest {what} {self.value:.3e}{at}'


def _where(index: int, recorded: Vector, replayed: Vector) -> str:
    if recorded is None or replayed is None:
        return 'computed only in the recording' if replayed is None else 'computed only in the replay'
    if len(recorded) != len(replayed):
        return f'{len(recorded)} values recorded, {len(replayed)} replayed'
    return f'recorded {recorded[index]:+.6f}, replayed {replayed[index]:+.6f}'


def _largest(name: str, ticks: Sequence[float], pairs: Sequence[tuple[Vector, Vector]]) -> Largest:
    """The largest element-wise difference of the ``(recorded, replayed)`` pairs, one per tick."""
    best = Largest(name, 0.0)
    for t, (recorded, replayed) in zip(ticks, pairs):
        if recorded is None and replayed is None:
            continue
        if recorded is None or replayed is None or len(recorded) != len(replayed):
            value, index = math.inf, 0
        elif recorded.size == 0:
            value, index = 0.0, 0
        else:
            with np.errstate(invalid='ignore'):  # inf - inf: equal bounds are no difference
                diff = np.where((recorded == replayed) | (np.isnan(recorded) & np.isnan(replayed)), 0.0,
                                np.abs(recorded - replayed))
            diff = np.where(np.isnan(diff), np.inf, diff)
            index = int(np.argmax(diff))
            value = float(diff[index])
        if value > best.value or best.t is None:
            best = Largest(name, value, t, _where(index, recorded, replayed))
    return best


def command_differences(ticks: Sequence[float], recorded: Sequence[Any], replayed: Sequence[Any]) -> list[Largest]:
    """Per joint of the recorded commands (``sensor_msgs/JointState`` velocities, by name)."""
    joints = next((list(msg.name) for msg in recorded if msg is not None), [])

    def velocity(msg, joint: str) -> Vector:
        return None if msg is None else np.array([dict(zip(msg.name, msg.velocity)).get(joint, math.nan)])

    return [_largest(joint, ticks, [(velocity(a, joint), velocity(b, joint)) for a, b in zip(recorded, replayed)])
            for joint in joints]


def task_difference(task: str, ticks: Sequence[float], recorded: Sequence[Any], replayed: Sequence[Any]) -> Largest:
    """Of a Task's error (``itasc_msgs/TaskState``: ``error``) or of its rows
    (``itasc_msgs/ConstraintRows``: what its controller asks of the Solver, ``desired``, ``lower``,
    ``upper``), over their components."""
    def values(msg) -> Vector:
        if msg is None:
            return None
        if hasattr(msg, 'error'):
            return np.asarray(msg.error, dtype=float)
        return np.concatenate([np.asarray(v, dtype=float) for v in (msg.desired, msg.lower, msg.upper)])

    return _largest(task, ticks, [(values(a), values(b)) for a, b in zip(recorded, replayed)])
