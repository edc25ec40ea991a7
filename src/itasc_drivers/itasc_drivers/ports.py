"""The ports every Driver has (paper §4.1, §4.2): joint velocity commands in, joint states out,
so that swapping the Driver moves the same program from simulation to a real robot."""

from __future__ import annotations

from sensor_msgs.msg import JointState

from itasc_core.communication.ports import PortSpec
from itasc_core.itasc.entities.robot_entity import joint_positions
from itasc_core.itasc.entities.messages import PROGRAM_VELOCITIES

__all__ = ['driver_ports']


def driver_ports(robot: str) -> list[PortSpec]:
    return [
        PortSpec(name='command', direction='input', msg_type=JointState, type='joint_velocities',
                 semantics=PROGRAM_VELOCITIES),
        PortSpec(name='joint_state', direction='output', msg_type=JointState, type='joint_state',
                 semantics=joint_positions(robot)),
    ]
