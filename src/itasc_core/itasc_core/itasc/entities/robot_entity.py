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

import math
from typing import Any

from sensor_msgs.msg import JointState

from ...communication.ports import PortSpec
from ...computation.functional_entity import FunctionalEntity
from ..robot import Robot
from .messages import stamp

__all__ = ['RobotEntity', 'joint_positions']


def joint_positions(robot: str) -> str:
    """Semantics of a robot's joint positions."""
    return f'JointPositions({robot})'


class RobotEntity(FunctionalEntity):
    """Measured joint state of one robot, by name, in model order."""

    PARAMETERS = {'robot': 'robot', 'urdf': '', 'base': 'fixed'}

    @classmethod
    def port_specs(cls, params: dict[str, Any]) -> list[PortSpec]:
        semantics = joint_positions(params['robot'])
        return [
            PortSpec(name='measured', direction='input', msg_type=JointState, type='joint_state',
                     semantics=semantics),
            PortSpec(name='joint_state', direction='output', msg_type=JointState, type='joint_state',
                     semantics=semantics),
        ]

    def configure(self, params: dict[str, Any]) -> None:
        self.robot = Robot(params['robot'], params['urdf'], base=params['base'])
        self.joint_names = list(self.robot.joint_names)
        self._missing_reported = False

    def update(self, t: float) -> None:
        msg = self.inputs['measured'].latest
        if msg is None:
            return
        by_name = dict(zip(msg.name, msg.position))
        missing = [n for n in self.joint_names if n not in by_name]
        if missing:
            if not self._missing_reported:
                self._missing_reported = True
                self.raise_event(f'e_{self.robot.name}_joints_missing', detail=', '.join(missing))
            return
        positions = [float(by_name[n]) for n in self.joint_names]
        if not all(math.isfinite(p) for p in positions):
            self.raise_event('e_emergency', priority=True,
                             detail=f'{self.robot.name}: non-finite joint positions')
            return
        out = JointState(name=self.joint_names, position=positions)
        out.header.stamp = stamp(t)
        self.outputs['joint_state'].write(out)

    def fault_persists(self) -> str | None:
        """Before a recovery from Safety: are the latest measured joint positions still not finite?"""
        msg = self.inputs['measured'].latest
        by_name = dict(zip(msg.name, msg.position)) if msg is not None else {}
        bad = [n for n in self.joint_names if n in by_name and not math.isfinite(by_name[n])]
        return f'{self.robot.name}: non-finite joint positions {bad}' if bad else None
