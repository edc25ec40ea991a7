"""The optimization problem a Solver receives and what it returns (paper §2.2, §4.1 "Solver").

Each Task contributes ``ConstraintRows`` on the program-wide joint velocity vector qdot: equality
rows ``J qdot = desired`` or inequality rows ``lower <= J qdot <= upper``, with a weight per row
and a priority level (0 = highest). Within a level the weighted residual
``sum_i weights_i * (J_i qdot - desired_i)^2`` is minimised (weights multiply *squared*
residuals; a pink ``cost`` c corresponds to ``weights = c**2``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

__all__ = ['ConstraintRows', 'SolverResult', 'STATUSES', 'velocity_bounds', 'group_levels']

STATUSES = ('ok', 'singular', 'infeasible', 'saturated')


@dataclass(slots=True, eq=False)
class ConstraintRows:
    """Rows one Task contributes: m rows on n joint velocities."""

    task: str
    priority: int
    J: np.ndarray  # (m, n)
    desired: np.ndarray  # (m,) equality target on J qdot (ydot_desired)
    lower: np.ndarray  # (m,) inequality bounds on J qdot (+-inf allowed)
    upper: np.ndarray  # (m,)
    weights: np.ndarray  # (m,) > 0, multiply squared residuals
    inequality: bool = False

    @classmethod
    def equality(cls, task: str, J: np.ndarray, desired: np.ndarray, *, priority: int = 0,
                 weights: float | np.ndarray = 1.0) -> ConstraintRows:
        desired = np.asarray(desired, dtype=float)
        return cls(task, priority, np.asarray(J, dtype=float), desired, desired, desired,
                   np.broadcast_to(np.asarray(weights, dtype=float), desired.shape).copy())

    @classmethod
    def bounds(cls, task: str, J: np.ndarray, lower: np.ndarray, upper: np.ndarray, *,
               priority: int = 0, weights: float | np.ndarray = 1.0) -> ConstraintRows:
        lower = np.asarray(lower, dtype=float)
        upper = np.asarray(upper, dtype=float)
        return cls(task, priority, np.asarray(J, dtype=float), np.zeros_like(lower), lower,
                   upper, np.broadcast_to(np.asarray(weights, dtype=float), lower.shape).copy(),
                   inequality=True)


@dataclass(slots=True, eq=False)
class SolverResult:
    """One Solver step. ``status`` is the most severe of infeasible > singular > saturated > ok."""

    qdot: np.ndarray
    status: str = 'ok'
    singular: bool = False
    infeasible: bool = False
    saturated: bool = False
    min_singular_value: float = float('nan')
    damping: float = 0.0
    solve_time: float = 0.0
    tasks: list[str] = field(default_factory=list)
    #: Tasks whose rows could not be met (infeasible): a failed level, or a violated inequality.
    violated: list[str] = field(default_factory=list)

    def set_status(self) -> None:
        self.status = ('infeasible' if self.infeasible else 'singular' if self.singular
                       else 'saturated' if self.saturated else 'ok')


def velocity_bounds(q: np.ndarray, lower: np.ndarray, upper: np.ndarray,
                    velocity_limit: np.ndarray, dt: float, gain: float
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Joint velocity box: position limits over one cycle, ``gain * (lower - q) / dt <= qdot <=
    gain * (upper - q) / dt`` (0 < gain <= 1 is the safety factor), intersected with
    ``|qdot| <= velocity_limit``. A joint already beyond a limit may move back at full speed,
    so the box is never empty. Infinite entries stay infinite."""
    k = gain / dt
    lo = np.minimum(np.maximum(k * (lower - q), -velocity_limit), velocity_limit)
    hi = np.minimum(np.maximum(k * (upper - q), -velocity_limit), velocity_limit)
    return lo, hi


def group_levels(rows: Sequence[ConstraintRows]) -> list[list[ConstraintRows]]:
    """Rows grouped by priority, highest priority (lowest number) first; empty rows dropped."""
    levels: dict[int, list[ConstraintRows]] = {}
    for r in rows:
        if r.J.shape[0]:
            levels.setdefault(r.priority, []).append(r)
    return [levels[p] for p in sorted(levels)]
