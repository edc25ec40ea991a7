"""ROS 2 Functional Entities of the constraint-based program (paper §4.1, §4.2): Robot, Scene and
Solver, wrapping the plain-Python math of :mod:`itasc_core.itasc`."""

from .robot_entity import RobotEntity
from .scene_entity import SceneEntity
from .solver_entity import SolverEntity

__all__ = ['RobotEntity', 'SceneEntity', 'SolverEntity']
