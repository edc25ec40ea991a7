"""iTaSC Solvers (paper §4.1 "Solver"): prioritised weighted damped least squares and a cascade of
QPs, both taking ``ConstraintRows`` and returning a ``SolverResult``, registered kinds
(:mod:`.kind`, entry point group ``itasc.solvers``). Names are imported on first use
(:mod:`itasc_core.lazy`): a process that runs the ``wdls`` Solver never loads qpsolvers."""

from __future__ import annotations

from typing import TYPE_CHECKING

from ...lazy import lazy_exports

if TYPE_CHECKING:
    from .kind import SOLVERS, Solver
    from .problem import STATUSES, ConstraintRows, SolverResult, group_levels, velocity_bounds
    from .qp import QpSolver
    from .wdls import WdlsSolver

__all__ = ['Solver', 'SOLVERS', 'ConstraintRows', 'SolverResult', 'STATUSES', 'QpSolver', 'WdlsSolver',
           'group_levels', 'velocity_bounds']

__getattr__ = lazy_exports(__name__, {
    'Solver': '.kind', 'SOLVERS': '.kind', 'QpSolver': '.qp', 'WdlsSolver': '.wdls',
    **dict.fromkeys(('STATUSES', 'ConstraintRows', 'SolverResult', 'group_levels', 'velocity_bounds'), '.problem')})
