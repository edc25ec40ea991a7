"""What each Task of a recorded run meant (paper §2.2, §4.1): an equality Task's error, an
inequality Task's distance against its bounds, and the Running sub-FSM transitions (§6.1).

For an inequality (distance) Task the error is 0 whenever the bound holds: what matters is
``output[0]`` (the distance) against ``d_min``/``d_max``, and when the bound was *active*, i.e.
when the Solver's commanded motion lay on it (``J qdot`` equal to the row's ``lower`` or
``upper``). The recording does not carry the model, but its constraint rows do carry the bounds:
the Constraint Controller sends ``lower = kp (d_min - d)`` and ``upper = kp (d_max - d)``, so a
straight-line fit of ``lower`` against the distance ``d`` gives ``d_min`` exactly (and ``kp``);
when the fit is not exact (the gain changed during the run) no bound is claimed.
"""

from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ['InequalityTrace', 'inequality_traces', 'sub_fsm_marks', 'draw_marks']

TASK_STATE = 'itasc_msgs/msg/TaskState'
CONSTRAINT_ROWS = 'itasc_msgs/msg/ConstraintRows'
JOINT_STATE = 'sensor_msgs/msg/JointState'
COORDINATOR_STATE = 'itasc_msgs/msg/CoordinatorState'
RUNNING = 'Active.Run.Running.'
#: ``J qdot`` within this (relative) tolerance of a bound: the bound is active.
ACTIVE_TOLERANCE = 1e-6


@dataclass
class InequalityTrace:
    """An inequality Task over the run: per tick its time (s from the recording's start),
    distance, and whether a bound was active; its bounds (None: none, or not recovered)."""

    task: str
    t: np.ndarray
    distance: np.ndarray
    active: np.ndarray
    d_min: float | None
    d_max: float | None


def _key(stamp) -> tuple[int, int]:
    return stamp.sec, stamp.nanosec


def _bound(distance: np.ndarray, bound: np.ndarray) -> float | None:
    """``d_b`` of ``bound = kp (d_b - distance)``, if that holds exactly at every tick."""
    finite = np.isfinite(bound)
    d, b = distance[finite], bound[finite]
    if len(d) < 2 or np.ptp(d) <= 0:
        return None
    slope, intercept = np.polyfit(d, b, 1)
    if slope >= 0 or np.max(np.abs(slope * d + intercept - b)) > 1e-9 * max(1.0, np.max(np.abs(b))):
        return None
    return float(-intercept / slope)


def inequality_traces(series: dict[str, list[tuple[float, Any]]], types: dict[str, str]) -> list[InequalityTrace]:
    """Every inequality Task of a recording (its ``Rows/rows`` say ``inequality``)."""
    rows: dict[str, dict] = defaultdict(dict)
    for topic, items in series.items():
        if types[topic] == CONSTRAINT_ROWS:
            for _, msg in items:
                if msg.inequality:
                    rows[msg.task][_key(msg.stamp)] = msg
    commands = {_key(msg.header.stamp): msg for topic, items in series.items()
                if types[topic] == JOINT_STATE and topic.endswith('/Solver/command') for _, msg in items}
    traces = []
    for topic, items in sorted(series.items()):
        if types[topic] != TASK_STATE or not items or items[0][1].task not in rows:
            continue
        task_rows = rows[items[0][1].task]
        samples = [(t, msg) for t, msg in items if len(msg.output)]
        t = np.array([s[0] for s in samples])
        distance = np.array([s[1].output[0] for s in samples])
        paired = [task_rows.get(_key(msg.stamp)) for _, msg in samples]
        lower = np.array([r.lower[0] if r is not None else np.nan for r in paired])
        upper = np.array([r.upper[0] if r is not None else np.nan for r in paired])
        active = np.array([_on_bound(r, commands.get(_key(r.stamp))) if r is not None else False for r in paired],
                          dtype=bool)
        have = ~np.isnan(lower)
        traces.append(InequalityTrace(items[0][1].task, t, distance, active,
                                      _bound(distance[have], lower[have]), _bound(distance[have], upper[have])))
    return traces


def _on_bound(rows, command) -> bool:
    """Whether the commanded joint velocities put the row's ``J qdot`` on its lower or upper bound."""
    if command is None or not len(command.velocity):
        return False
    index = {name: i for i, name in enumerate(command.name)}
    if any(name not in index for name in rows.joint_names):
        return False
    qdot = np.array([command.velocity[index[name]] for name in rows.joint_names])
    ydot = np.asarray(rows.jacobian).reshape(rows.rows, -1)[0] @ qdot
    return any(np.isfinite(b) and abs(ydot - b) <= ACTIVE_TOLERANCE * max(1.0, abs(b))
               for b in (rows.lower[0], rows.upper[0]))


def sub_fsm_marks(series: dict[str, list[tuple[float, Any]]], types: dict[str, str]) -> list[tuple[float, str]]:
    """``[(t, sub-state), ...]``: the transitions of the uppermost composite's Running sub-FSM."""
    with_sub_fsm = [topic for topic, items in series.items() if types[topic] == COORDINATOR_STATE
                    and any(msg.state.startswith(RUNNING) for _, msg in items)]
    if not with_sub_fsm:
        return []
    top = min(with_sub_fsm, key=lambda topic: (topic.count('/'), topic))
    return [(t, msg.state.removeprefix(RUNNING)) for t, msg in series[top] if msg.state.startswith(RUNNING)]


def draw_marks(ax, marks: list[tuple[float, str]], *, label: bool = True) -> None:
    """Vertical lines at the sub-FSM transitions, named by the state entered."""
    for t, state in marks:
        ax.axvline(t, color='tab:purple', linewidth=0.9, linestyle=':')
        if label:
            ax.text(t, 1.0, f' {state}', transform=ax.get_xaxis_transform(), rotation=0, fontsize=7,
                    color='tab:purple', va='bottom', ha='left', clip_on=False)
