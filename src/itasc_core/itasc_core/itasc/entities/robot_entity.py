"""RobotEntity: the Functional Entity of one Robot of a constraint-based program (paper §4.1
"Robots and Objects", §4.2).

It reads the robot's measured joint state from its Driver (``sensor_msgs/JointState``, joints
mapped by name in any order, joints of other robots or grippers ignored), checks it against the
robot's kinematic model (all joints present, finite values) and hands it on in the model's order
of velocity coordinates, which is what the Scene composes. The kinematic model itself (URDF via
Pinocchio, :class:`itasc_core.itasc.Robot`) gives the joint names; forward kinematics is
computed once per tick by the Scene, which owns the world model.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import Field
from sensor_msgs.msg import JointState

from ...communication.event_names import JOINTS_MISSING, SAFETY_EVENT, event
from ...communication.ports import PortSpec
from ...computation.functional_entity import FunctionalEntity
from ...computation.parameters import ParameterModel
from ...finite import all_finite
from ..robot import Robot
from .messages import JointSample

__all__ = ['RobotEntity', 'joint_positions']


def joint_positions(robot: str) -> str:
    """Semantics of a robot's joint positions."""
    return f'JointPositions({robot})'


class RobotEntity(FunctionalEntity):
    """Measured joint state of one robot, by name, in model order."""

    class Parameters(ParameterModel):
        robot: str = Field(default='robot', frozen=True)
        """The robot's name."""
        urdf: str = Field(default='', frozen=True)
        """Its URDF file (absolute path)."""
        base: Literal['fixed', 'planar', 'free_flyer'] = Field(default='fixed', frozen=True)
        """Its base: fixed, or a mobile base's joints."""

    @classmethod
    def port_specs(cls, params: Parameters) -> list[PortSpec]:
        semantics = joint_positions(params.robot)
        return [
            PortSpec(name='measured', direction='input', msg_type=JointState, type='joint_state',
                     semantics=semantics),
            PortSpec(name='joint_state', direction='output', msg_type=JointState, type='joint_state',
                     semantics=semantics),
        ]

    def configure(self, params: Parameters) -> None:
        self.robot = Robot(params.robot, params.urdf, base=params.base)
        self.joint_names = tuple(self.robot.joint_names)
        self._missing_reported = False
        self._order: tuple[tuple[str, ...], np.ndarray | None] = ((), None)  # measured names -> model order

    def _index(self, names: tuple[str, ...]) -> np.ndarray | None:
        """Where each joint of the model is in ``names`` (None if one is missing), cached while the
        driver keeps its order."""
        if self._order[0] != names:
            where = {n: i for i, n in enumerate(names)}
            found = [where.get(n) for n in self.joint_names]
            self._order = (names, None if None in found else np.array(found, dtype=int))
        return self._order[1]

    def update(self, t: float) -> None:
        msg = self.inputs['measured'].latest
        if msg is None:
            return
        index = self._index(msg.name)
        if index is None or len(msg.position) != len(msg.name):
            if not self._missing_reported:
                self._missing_reported = True
                present = set(msg.name[:len(msg.position)])
                self.raise_event(event(self.robot.name, JOINTS_MISSING),
                                 detail=', '.join(n for n in self.joint_names if n not in present))
            return
        positions = msg.position[index]
        if not all_finite(positions):
            self.raise_event(SAFETY_EVENT, priority=True,
                             detail=f'{self.robot.name}: non-finite joint positions')
            return
        self.outputs['joint_state'].write(JointSample(t, self.joint_names, positions))

    def fault_persists(self) -> str | None:
        """Before a recovery from Safety: are the latest measured joint positions still not finite?"""
        msg = self.inputs['measured'].latest
        by_name = dict(zip(msg.name, msg.position)) if msg is not None else {}
        bad = [n for n in self.joint_names if n in by_name and not np.isfinite(by_name[n])]
        return f'{self.robot.name}: non-finite joint positions {bad}' if bad else None
