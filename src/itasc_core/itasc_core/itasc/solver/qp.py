"""Prioritised QP Solver: a cascade of quadratic programs through ``qpsolvers`` (paper §2.2 with
inequality constraints, §4.1 "Solver").

Level k (priority order) solves, over qdot and one slack per inequality row of the level::

    min  1/2 sum_eq w (J qdot - ydot)^2 + 1/2 sum_ineq w s^2 + 1/2 rho qdot^T W_q qdot
    s.t. lower <= J qdot + s <= upper                   (this level's inequality rows)
         Z^T qdot = Z^T qdot*_{k-1}                      (higher levels' equality rows, kept)
         min(l, J qdot*) <= J qdot <= max(u, J qdot*)    (higher levels' inequalities, slack kept)
         lb <= qdot <= ub                                (velocity + position limits, see
                                                          ``velocity_bounds``)

``Z`` is an orthonormal basis of the row space of all higher-level equality rows, so redundant
rows never reach the backend. With all tasks at one priority this is exactly pink's IK QP
(``weights = cost**2``, ``regularization = damping``, ``position_limit_gain =
config_limit_gain``). If a level fails the result of the last solved level is returned with
status ``infeasible``; an inequality row left violated also reports ``infeasible``.

A first level of inequality rows only (obstacle distances, limits: the usual top of a cascade)
that the rest point (qdot = 0, or the nearest velocity within the bounds) already meets has that
rest point as its exact optimum (zero slack, the least regularisation term the bounds allow), so
its QP is not solved: while the robot is clear of its constraints a step solves one QP less.

Singularity is measured per equality task: the smallest non-zero singular value of the task's
Jacobian (rows scaled by sqrt of their weight relative to the task's largest), in the directions
higher levels leave free. Below ``singularity_epsilon`` the step reports ``singular``; the
regularisation and the joint limits keep qdot bounded there, so nothing else changes. Per task,
not per level: a low-weight task sharing a level (a posture regularising a frame task) is not a
singularity. The SVDs cost about a third of a step, and a singularity builds up over many ticks,
so each task's runs every ``singularity_check_period``-th step, the tasks' checks spread over the
period (all of them in one step made that step a third longer: the tail of a control loop's ticks);
a step reports the smallest of its equality tasks' last values.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from time import perf_counter

import numpy as np
import qpsolvers
from scipy.linalg.lapack import dgeqp3 as _geqp3
from scipy.linalg.lapack import dgesvd as _gesvd
from scipy.linalg.lapack import dorgqr as _orgqr

from pydantic import Field, field_validator

from ...computation.parameters import ParameterModel
from ...finite import all_finite
from .kind import Solver
from .problem import ConstraintRows, SolverResult, group_levels, velocity_bounds

__all__ = ['QpSolver', 'QpSettings']


class QpSettings(ParameterModel):
    """The settings of the ``qp`` Solver."""

    backend: str = 'daqp'
    """The QP solver: any solver ``qpsolvers`` has installed."""
    regularization: float = Field(default=1e-6, gt=0)
    """Weight of the joint-velocity norm."""

    @field_validator('backend')
    @classmethod
    def _available(cls, value: str) -> str:
        if value not in qpsolvers.available_solvers:
            raise ValueError(f"QP backend '{value}' is not available; available: {qpsolvers.available_solvers}")
        return value

_EQUALITY = 5  # DAQP constraint sense: equality
_BIG = 1e9  # stands for infinity where a backend cannot take inf


class QpSolver(Solver):
    """A cascade of QPs, one per priority level, with joint limits and task inequalities
    (``backend`` any qpsolvers solver; ``regularization`` the weight of the joint-velocity norm)."""

    Parameters = QpSettings

    def __init__(self, *, backend: str = 'daqp', direct: bool = True,
                 joint_weights: float | np.ndarray = 1.0, regularization: float = 1e-8,
                 position_limit_gain: float = 0.5, slack_tolerance: float = 1e-6,
                 rank_tolerance: float = 1e-6, singularity_epsilon: float = 0.02,
                 singularity_check_period: int = 10, backend_options: dict | None = None) -> None:
        """``backend``: any ``qpsolvers.available_solvers`` name. ``direct``: with 'daqp', call
        DAQP's own API instead of ``qpsolvers.solve_qp`` (same solver, ~20 us less per QP).
        ``regularization`` rho weighs the joint-space term (``joint_weights`` W_q);
        ``position_limit_gain`` in (0, 1] is the share of the distance to a position limit
        allowed in one cycle; an inequality row violated by more than ``slack_tolerance``
        reports infeasible; higher-level equality directions weaker than ``rank_tolerance``
        (relative, pivoted QR) are not locked; ``singularity_epsilon``: see the module docstring;
        ``backend_options`` go to the backend."""
        if backend not in qpsolvers.available_solvers:
            raise ValueError(f'QP backend {backend!r} is not available; available: '
                             f'{qpsolvers.available_solvers}')
        self.backend = backend
        self.direct = direct and backend == 'daqp'
        if self.direct:
            import daqp
            self._daqp = daqp.solve
        self.joint_weights = np.asarray(joint_weights, dtype=float)
        self.regularization = regularization
        self.position_limit_gain = position_limit_gain
        self.slack_tolerance = slack_tolerance
        self.rank_tolerance = rank_tolerance
        self.singularity_epsilon = singularity_epsilon
        self.singularity_check_period = max(1, int(singularity_check_period))
        self._step = 0
        #: task -> its smallest singular value at its last check
        self._singular_values: dict[str, float] = {}
        defaults = {'osqp': {'eps_abs': 1e-7, 'eps_rel': 1e-7, 'verbose': False,
                             'raise_error': False},
                    'proxqp': {'eps_abs': 1e-9, 'eps_rel': 0.0}}
        self.backend_options = {**defaults.get(backend, {}), **(backend_options or {})}

    @classmethod
    def create(cls, params: QpSettings, *, joint_weights: float | np.ndarray,  # type: ignore[override]
               position_limit_gain: float) -> QpSolver:
        return cls(backend=params.backend, regularization=params.regularization, joint_weights=joint_weights,
                   position_limit_gain=position_limit_gain)

    def solve(self, rows: Sequence[ConstraintRows], *, q: np.ndarray, lower: np.ndarray,
              upper: np.ndarray, velocity_limit: np.ndarray, dt: float) -> SolverResult:
        t0 = perf_counter()
        n = q.shape[0]
        result = SolverResult(np.zeros(n), tasks=[r.task for r in rows])
        lb, ub = velocity_bounds(q, lower, upper, velocity_limit, dt, self.position_limit_gain)
        qdot = np.minimum(np.maximum(0.0, lb), ub)  # fallback: rest, or back within limits
        reg = self.regularization * self.joint_weights  # scalar or per joint
        locked = np.zeros((0, n))  # Z^T: orthonormal rows spanning higher-level equality rows
        kept: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []  # higher-level inequalities
        levels = group_levels(rows)
        period, step = self.singularity_check_period, self._step
        self._step += 1
        singular_values = self._singular_values
        n_eq = sum(not r.inequality for r in rows)
        i_eq = 0  # the equality task's place in this step: its check's phase in the period
        for k, level in enumerate(levels):
            eq = [r for r in level if not r.inequality]
            ineq = [r for r in level if r.inequality]
            for r in eq:
                if (step - i_eq * period // n_eq) % period == 0:
                    singular_values[r.task] = _smallest_singular_value(_free_part(r, locked))
                i_eq += 1
            at_rest = k == 0 and not eq and _satisfied(ineq, qdot)
            if at_rest:
                x = qdot  # the rest point meets every row: it is this level's optimum, no QP
            else:
                x = self._solve_level(n, eq, ineq, locked, qdot, kept, lb, ub, reg)
            if x is None:
                result.infeasible = True
                result.violated += [r.task for r in level]
                break
            qdot = np.minimum(np.maximum(x, lb), ub)
            if k == len(levels) - 1:
                break
            for r in ineq:
                if at_rest:  # within its bounds already: they are kept as they are
                    kept.append((r.J, r.lower, r.upper))
                    continue
                y = r.J.dot(qdot)
                kept.append((r.J, np.minimum(r.lower, y), np.maximum(r.upper, y)))
            if eq:
                locked = self._lock(locked, np.concatenate([r.J for r in eq]))
                if locked.shape[0] == n:
                    break
        for r in rows:
            if r.inequality:
                y = r.J.dot(qdot)
                violation = np.maximum(r.lower - y, y - r.upper)
                if violation.max(initial=0.0) > self.slack_tolerance and r.task not in result.violated:
                    result.infeasible = True
                    result.violated.append(r.task)
        result.saturated = _saturated(qdot, lb, ub)
        if len(singular_values) > n_eq:  # tasks switched off since: their values no longer count
            self._singular_values = singular_values = {
                r.task: singular_values[r.task] for r in rows if not r.inequality and r.task in singular_values}
        result.min_singular_value = min((singular_values.get(r.task, math.inf) for r in rows if not r.inequality),
                                        default=math.inf)
        result.singular = bool(result.min_singular_value < self.singularity_epsilon)
        result.qdot = qdot
        result.set_status()
        result.solve_time = perf_counter() - t0
        return result

    def _lock(self, locked: np.ndarray, J: np.ndarray) -> np.ndarray:
        """Extend the orthonormal basis of locked directions with the row space of J
        (rank-revealing QR with column pivoting of the part of J^T not yet locked)."""
        if locked.shape[0]:
            J = J - (J @ locked.T) @ locked
        qr, _, tau, _, _ = _geqp3(J.T)
        k = min(J.shape)
        diagonal = np.abs(qr.diagonal())
        rank = int(np.count_nonzero(diagonal > self.rank_tolerance * max(1.0, diagonal[0])))
        if not rank:
            return locked
        q, _, _ = _orgqr(qr[:, :k], tau[:k])
        return np.concatenate([locked, q[:, :rank].T])

    def _solve_level(self, n: int, eq: list[ConstraintRows], ineq: list[ConstraintRows],
                     locked: np.ndarray, previous: np.ndarray,
                     kept: list[tuple[np.ndarray, np.ndarray, np.ndarray]],
                     lb: np.ndarray, ub: np.ndarray, reg: float | np.ndarray) -> np.ndarray | None:
        # H, f, C and the bounds are filled in place: at 1 kHz the numpy calls that stacked
        # them block by block (hstack, eye, concatenate) cost more than the QP itself
        ms = 0
        for r in ineq:
            ms += r.J.shape[0]
        m = n + ms
        H = np.zeros((m, m))
        f = np.zeros(m)
        if eq:
            J = np.concatenate([r.J for r in eq]) if len(eq) > 1 else eq[0].J
            w = np.concatenate([r.weights for r in eq]) if len(eq) > 1 else eq[0].weights
            d = np.concatenate([r.desired for r in eq]) if len(eq) > 1 else eq[0].desired
            WJ = w[:, None] * J
            H[:n, :n] = J.T.dot(WJ)  # ndarray.dot: half of np.matmul's cost on arrays this small
            np.dot(d, WJ, out=f[:n])
            f[:n] *= -1.0
        H.flat[:n * m:m + 1] += reg
        mk = 0
        for J, _, _ in kept:
            mk += J.shape[0]
        ml = locked.shape[0]
        # general constraints C x in [cl, cu]: level inequalities (with their slacks), kept
        # higher-level inequalities, then the locked equalities
        C = np.zeros((ms + mk + ml, m))
        lower = np.empty(m - ms + C.shape[0])
        upper = np.empty_like(lower)
        lower[:n], upper[:n] = lb, ub
        row = 0
        for r in ineq:
            k = r.J.shape[0]
            C[row:row + k, :n] = r.J
            H.flat[(n + row) * (m + 1):(n + row + k) * (m + 1):m + 1] = r.weights
            lower[n + row:n + row + k], upper[n + row:n + row + k] = r.lower, r.upper
            row += k
        if ms:
            C.flat[n:ms * m:m + 1] = 1.0  # each row's slack
            H.flat[n * (m + 1)::m + 1] += reg if reg.ndim == 0 else reg.sum() / n  # the mean
        for J, lo, up in kept:
            k = J.shape[0]
            C[row:row + k, :n] = J
            lower[n + row:n + row + k], upper[n + row:n + row + k] = lo, up
            row += k
        if ml:
            C[row:, :n] = locked
            lower[n + row:] = upper[n + row:] = locked @ previous
        solve = self._solve_daqp if self.direct else self._solve_qpsolvers
        return solve(H, f, C, lower, upper, ms + mk, n)

    def _solve_daqp(self, H: np.ndarray, f: np.ndarray, C: np.ndarray, lower: np.ndarray,
                    upper: np.ndarray, n_ineq: int, n: int) -> np.ndarray | None:
        """``lower``/``upper``: n simple bounds on qdot, then the bounds of the rows of C."""
        sense = None
        if C.shape[0] > n_ineq:
            sense = np.zeros(lower.shape[0], dtype=np.int32)
            sense[n + n_ineq:] = _EQUALITY
        x, _, exitflag, _ = self._daqp(H, f, C, upper, lower, sense)
        return x[:n] if exitflag >= 1 and all_finite(x) else None

    def _solve_qpsolvers(self, H: np.ndarray, f: np.ndarray, C: np.ndarray, lower: np.ndarray,
                         upper: np.ndarray, n_ineq: int, n: int) -> np.ndarray | None:
        m = H.shape[0]
        lb, ub, cl, cu = lower[:n], upper[:n], lower[n:], upper[n:]
        Ci, li, ui = C[:n_ineq], cl[:n_ineq], cu[:n_ineq]
        up, lo = np.isfinite(ui), np.isfinite(li)
        G = np.concatenate([Ci[up], -Ci[lo]]) if up.any() or lo.any() else None
        h = np.concatenate([ui[up], -li[lo]]) if G is not None else None
        A = C[n_ineq:] if C.shape[0] > n_ineq else None
        b = cu[n_ineq:] if A is not None else None
        lbx = np.concatenate([np.maximum(lb, -_BIG), np.full(m - n, -_BIG)])
        ubx = np.concatenate([np.minimum(ub, _BIG), np.full(m - n, _BIG)])
        if self.backend == 'osqp':
            from scipy import sparse
            H, G, A = (None if M is None else sparse.csc_matrix(M) for M in (H, G, A))  # type: ignore[assignment]
        try:
            x = qpsolvers.solve_qp(H, f, G, h, A, b, lbx, ubx, solver=self.backend,
                                   **self.backend_options)
        except Exception:  # noqa: BLE001 - a backend failing on a degenerate level is an infeasible level
            return None
        return None if x is None or not np.isfinite(x).all() else x[:n]


def _saturated(qdot: np.ndarray, lb: np.ndarray, ub: np.ndarray) -> bool:
    """Whether a bound shaped the solution (a zero bound: the joint rests exactly at its limit).
    Over Python floats: for a few joints ten numpy calls cost several times this loop."""
    for x, lo, hi in zip(qdot.tolist(), lb.tolist(), ub.tolist()):
        if (hi - x <= 1e-9 and abs(hi) > 1e-9) or (x - lo <= 1e-9 and abs(lo) > 1e-9):
            return True
    return False


def _satisfied(rows: list[ConstraintRows], qdot: np.ndarray) -> bool:
    """Whether ``qdot`` meets every inequality row of ``rows``."""
    for r in rows:
        for lo, y, hi in zip(r.lower.tolist(), r.J.dot(qdot).tolist(), r.upper.tolist()):
            if not lo <= y <= hi:  # a NaN meets no row
                return False
    return True


def _free_part(task: ConstraintRows, locked: np.ndarray) -> np.ndarray:
    """``task``'s Jacobian, rows scaled by sqrt of their weight relative to the task's largest,
    restricted to the directions not ``locked`` by higher levels."""
    sw = np.sqrt(task.weights)
    top = float(sw.max(initial=0.0))
    A = (sw / top)[:, None] * task.J if top > 0.0 else np.zeros_like(task.J)
    return A - (A @ locked.T) @ locked if locked.shape[0] else A


def _smallest_singular_value(part: np.ndarray, *, truncation: float = 1e-9) -> float:
    """The smallest non-zero singular value of ``part`` (inf if none; LAPACK's own SVD, without the
    singular vectors: half of numpy's for these few-row parts). Values below ``truncation`` relative
    to the largest are directions higher levels fixed or no row reaches, not singularities (as in
    the WDLS Solver)."""
    if not math.isfinite(part.sum()):
        return math.inf  # non-finite rows: the level reports infeasible
    # part.T is in Fortran order (no copy for LAPACK) and has the same singular values
    s = _gesvd(part.T, compute_uv=0, full_matrices=0)[1].tolist()
    floor = truncation * max(1.0, s[0]) if s else 0.0
    return min((v for v in s if v > floor), default=math.inf)
