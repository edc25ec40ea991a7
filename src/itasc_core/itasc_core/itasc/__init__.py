"""The plain-Python computation of a constraint-based program (paper §2.2, §4.1): Robot, Object,
Scene and Solvers on Pinocchio and qpsolvers. No ROS here; the ROS entities wrap these classes.

Its names are imported on first use (:mod:`itasc_core.lazy`): a process that hosts only Tasks
(``--deploy per-composite``) never pays for the Solvers' qpsolvers and scipy.sparse (about 0.4 s
of its start-up).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..lazy import lazy_exports

if TYPE_CHECKING:
    from .objects import Object
    from .robot import Robot, se3
    from .scene import Scene
    from .solver import ConstraintRows, QpSolver, SolverResult, WdlsSolver

__all__ = ['Robot', 'Object', 'Scene', 'se3', 'ConstraintRows', 'SolverResult', 'QpSolver',
           'WdlsSolver']

__getattr__ = lazy_exports(__name__, {
    'Robot': '.robot', 'se3': '.robot', 'Object': '.objects', 'Scene': '.scene', 'ConstraintRows': '.solver',
    'SolverResult': '.solver', 'QpSolver': '.solver', 'WdlsSolver': '.solver'})
