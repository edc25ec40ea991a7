"""iTaSC Solvers (paper §4.1 "Solver"): prioritised weighted damped least squares and a cascade of
QPs, both taking ``ConstraintRows`` and returning a ``SolverResult``."""

from .problem import STATUSES, ConstraintRows, SolverResult, group_levels, velocity_bounds
from .qp import QpSolver
from .wdls import WdlsSolver

__all__ = ['ConstraintRows', 'SolverResult', 'STATUSES', 'QpSolver', 'WdlsSolver',
           'group_levels', 'velocity_bounds']
