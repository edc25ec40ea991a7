"""Weighted damped least-squares Solver with strict priorities (paper §2.2, §4.1 "Solver"; the
original iTaSC WDLS solver).

Per priority level (highest first) the weighted task ``sqrt(W_y) J qdot = sqrt(W_y) ydot`` is
solved in the null space of all higher levels (null-space projection, Siciliano-Slotine), in
joint-weighted coordinates ``qdot = W_q^{-1/2} u`` so the minimum-norm part minimises
``qdot^T W_q qdot``. Each level's damped pseudo-inverse ``V diag(s / (s^2 + lambda^2)) U^T``
uses variable damping (Maciejewski/Nakamura): ``lambda^2 = lambda_max^2 (1 - (s_min/eps)^2)``
when the smallest non-zero singular value ``s_min`` (of the projected, weighted Jacobian)
drops below ``eps``, else 0; singular values below ``rank_tolerance`` (relative) are directions
already fixed by higher levels or structurally absent, truncated rather than damped. ``s_min``,
``eps`` and ``lambda`` are in unit-weight task units (divided by the level's largest
sqrt(weight)).
Inequality rows are handled by a small active-set loop: violated rows become equalities at their
bound and the cascade is solved again. Finally qdot is scaled uniformly so no joint exceeds its
velocity limit nor crosses a position limit within the cycle.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from time import perf_counter

import numpy as np
from scipy.linalg.lapack import dgesdd as _gesdd

from pydantic import Field

from ...computation.parameters import ParameterModel
from .kind import Solver
from .problem import ConstraintRows, SolverResult, group_levels, velocity_bounds

__all__ = ['WdlsSolver', 'WdlsSettings']


class WdlsSettings(ParameterModel):
    """The settings of the ``wdls`` Solver."""

    damping: float = Field(default=0.1, ge=0)
    """Largest damping near singularities [rad/s]."""


class WdlsSolver(Solver):
    """Weighted damped least squares, priorities by null-space projection, uniform velocity
    saturation (``damping``: the largest damping near singularities)."""

    Parameters = WdlsSettings

    def __init__(self, *, joint_weights: float | np.ndarray = 1.0, epsilon: float = 0.02,
                 max_damping: float = 0.05, rank_tolerance: float = 1e-9,
                 position_limit_gain: float = 0.5, inequality_iterations: int = 4) -> None:
        """``joint_weights`` (scalar or per joint, > 0) define the joint-space metric W_q;
        ``epsilon``/``max_damping`` the variable damping; ``position_limit_gain`` in (0, 1] the
        fraction of the distance to a position limit allowed in one cycle."""
        self.joint_weights = joint_weights
        self.epsilon = epsilon
        self.max_damping = max_damping
        self.rank_tolerance = rank_tolerance
        self.position_limit_gain = position_limit_gain
        self.inequality_iterations = inequality_iterations

    @classmethod
    def create(cls, params: WdlsSettings, *, joint_weights: float | np.ndarray,  # type: ignore[override]
               position_limit_gain: float) -> WdlsSolver:
        return cls(max_damping=params.damping, joint_weights=joint_weights, position_limit_gain=position_limit_gain)

    def solve(self, rows: Sequence[ConstraintRows], *, q: np.ndarray, lower: np.ndarray,
              upper: np.ndarray, velocity_limit: np.ndarray, dt: float) -> SolverResult:
        t0 = perf_counter()
        n = q.shape[0]
        result = SolverResult(np.zeros(n), tasks=[r.task for r in rows])
        levels = group_levels(rows)
        weights = np.asarray(self.joint_weights, dtype=float)
        scale = None if np.all(weights == 1.0) else np.broadcast_to(1.0 / np.sqrt(weights), (n,))
        active: dict[int, np.ndarray] = {}  # id(row) -> bound targets (nan = inactive)
        inequalities = [r for level in levels for r in level if r.inequality]
        for _ in range(self.inequality_iterations):
            qdot = self._cascade(levels, n, scale, active, result)
            changed = False
            for r in inequalities:
                y = r.J @ qdot
                target = active.setdefault(id(r), np.full(y.shape, np.nan))
                new = np.isnan(target) & ((y < r.lower - 1e-9) | (y > r.upper + 1e-9))
                if new.any():
                    target[new] = np.where(y[new] < r.lower[new], r.lower[new], r.upper[new])
                    changed = True
            if not changed:
                break
        for r in inequalities:
            y = r.J @ qdot
            if np.maximum(r.lower - y, y - r.upper).max() > 1e-6:
                result.infeasible = True
                result.violated.append(r.task)
        if not np.isfinite(qdot).all():
            qdot = np.zeros(n)
            result.infeasible = True
            result.violated += [r.task for r in rows]
        lo, hi = velocity_bounds(q, lower, upper, velocity_limit, dt, self.position_limit_gain)
        bound = np.where(qdot > 0.0, np.maximum(hi, 0.0), np.minimum(lo, 0.0))
        exceeded = np.abs(qdot) > np.abs(bound)
        if exceeded.any():
            qdot = qdot * max(float((bound[exceeded] / qdot[exceeded]).min()), 0.0)
            result.saturated = True
        result.qdot = qdot
        result.set_status()
        result.solve_time = perf_counter() - t0
        return result

    def _cascade(self, levels: list[list[ConstraintRows]], n: int, scale: np.ndarray | None,
                 active: dict[int, np.ndarray], result: SolverResult) -> np.ndarray:
        """One pass over the priority levels; returns qdot."""
        u = np.zeros(n)  # qdot = scale * u
        projector: np.ndarray | None = None  # None = identity
        free = n
        result.min_singular_value, result.damping, result.singular = math.inf, 0.0, False
        eps, tol = self.epsilon, self.rank_tolerance
        for k, level in enumerate(levels):
            parts = []
            for r in level:
                if not r.inequality:
                    parts.append((r.J, r.desired, r.weights))
                elif id(r) in active:
                    mask = ~np.isnan(active[id(r)])
                    if mask.any():
                        parts.append((r.J[mask], active[id(r)][mask], r.weights[mask]))
            if not parts:
                continue
            if len(parts) == 1:
                J, desired, weights = parts[0]
            else:
                J, desired, weights = (np.concatenate(x) for x in zip(*parts))
            sw = np.sqrt(weights)
            unit = float(sw.max())  # damping thresholds are in unit-weight task units
            A = sw[:, None] * J if scale is None else (sw[:, None] * J) * scale
            b = sw * desired
            if k:
                b -= A @ u
            U, s, Vt, info = _gesdd(A if projector is None else A @ projector,
                                    compute_uv=1, full_matrices=0)
            if info:  # non-finite rows: keep the higher levels' solution
                result.infeasible = True
                break
            rank = int(np.count_nonzero(s > tol * max(1.0, float(s[0]))))
            if not rank:  # fully determined by higher levels
                continue
            s_min = float(s[rank - 1]) / unit
            lam = 0.0
            if s_min < eps:
                lam = self.max_damping * math.sqrt(1.0 - (s_min / eps) ** 2)
                result.singular = True
            result.min_singular_value = min(result.min_singular_value, s_min)
            result.damping = max(result.damping, lam)
            s = s[:rank]
            u += Vt[:rank].T @ (s / (s * s + (lam * unit) ** 2) * (U[:, :rank].T @ b))
            free -= rank
            if free <= 0 or k == len(levels) - 1:
                break
            basis = Vt[:rank]
            projector = (np.eye(n) if projector is None else projector) - basis.T @ basis
        return u if scale is None else scale * u
