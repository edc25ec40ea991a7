"""The Driver ``ros2_control``: an existing ros2_control driver, reached through its controller's
command topic and ``joint_states`` (:class:`itasc_drivers.ros2_control_adapter.Ros2ControlAdapter`)."""

from __future__ import annotations

import sys
from collections.abc import Mapping
from typing import Any, Literal

from itasc_core.computation.parameters import ParameterModel, TopicName
from pydantic import Field

from .kind import DrivenRobot, Driver

__all__ = ['Ros2Control']


class Ros2ControlSection(ParameterModel):
    joint_states: TopicName = '/joint_states'
    """Where the driver publishes ``sensor_msgs/JointState``."""
    controller: TopicName
    """The ros2_control controller that takes the commands."""
    interface: Literal['velocity', 'position', 'trajectory'] = 'velocity'
    """What the controller takes: ``velocity`` or ``position`` (``std_msgs/Float64MultiArray``), or ``trajectory``
    (``trajectory_msgs/JointTrajectory``)."""
    joints: list[str] = Field(min_length=1)
    """The controller's joints, in the order its commands have them."""
    command_topic: TopicName | None = None
    """Where commands go (default ``/<controller>/commands``, or ``/<controller>/joint_trajectory``)."""


class Ros2Control(Driver):
    """An existing driver: ``joint_states`` topic, ``controller`` whose ``joints`` in order take
    ``interface`` commands on ``command_topic``."""

    Parameters = Ros2ControlSection
    entity = 'itasc_drivers.ros2_control_adapter:Ros2ControlAdapter'

    @classmethod
    def parameters(cls, section: Ros2ControlSection, robot: DrivenRobot) -> dict[str, Any]:
        return {'robot': robot.name, 'joints': list(section.joints), 'joint_states_topic': section.joint_states,
                'command_topic': _command_topic(section), 'interface': section.interface,
                'horizon': 2.0 / robot.rate}

    @classmethod
    def stand_in(cls, section: Ros2ControlSection, *, robot: DrivenRobot,
                 initial: Mapping[str, float]) -> list[str]:
        """``fake_ros2_control`` with the section's joints, controller, interface and topics,
        publishing at the application's rate."""
        return [sys.executable, '-m', 'itasc_drivers.fake_ros2_control', '--joints', ','.join(section.joints),
                '--initial', ','.join(repr(float(initial[j])) for j in section.joints),
                '--controller', section.controller.strip('/'), '--interface', section.interface,
                '--command-topic', _command_topic(section), '--joint-states', section.joint_states,
                '--rate', repr(float(robot.rate))]

    @classmethod
    def problem(cls, section: Ros2ControlSection, *, robot: DrivenRobot) -> tuple[tuple[str | int, ...], str] | None:
        joints = robot.joints
        for k, joint in enumerate(section.joints):
            if joint not in joints:
                return ('joints', k), f"robot '{robot.name}' has no joint '{joint}'; joints: {joints}"
        missing = [j for j in joints if j not in section.joints]
        if missing or len(set(section.joints)) != len(section.joints):
            return ('joints',), f'list every joint of the robot once (missing: {missing})'
        return None


def _command_topic(section: Ros2ControlSection) -> str:
    suffix = 'joint_trajectory' if section.interface == 'trajectory' else 'commands'
    return section.command_topic or f'/{section.controller.strip("/")}/{suffix}'
