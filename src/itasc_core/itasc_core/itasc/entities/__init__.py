"""ROS 2 Functional Entities of the constraint-based program (paper §4.1, §4.2): Robot, Scene and
Solver, wrapping the plain-Python math of :mod:`itasc_core.itasc`.

Imported on first use (:mod:`itasc_core.lazy`): a Task's entities read :mod:`.messages` only.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ...lazy import lazy_exports

if TYPE_CHECKING:
    from .robot_entity import RobotEntity
    from .scene_entity import SceneEntity
    from .solver_entity import SolverEntity

__all__ = ['RobotEntity', 'SceneEntity', 'SolverEntity']

__getattr__ = lazy_exports(__name__, {
    'RobotEntity': '.robot_entity', 'SceneEntity': '.scene_entity', 'SolverEntity': '.solver_entity'})
