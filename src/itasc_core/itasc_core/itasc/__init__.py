"""The plain-Python computation of a constraint-based program (paper §2.2, §4.1): Robot, Object,
Scene and Solvers on Pinocchio and qpsolvers. No ROS here; the ROS entities wrap these classes."""

from .objects import Object
from .robot import Robot, se3
from .scene import Scene
from .solver import ConstraintRows, QpSolver, SolverResult, WdlsSolver

__all__ = ['Robot', 'Object', 'Scene', 'se3', 'ConstraintRows', 'SolverResult', 'QpSolver',
           'WdlsSolver']
