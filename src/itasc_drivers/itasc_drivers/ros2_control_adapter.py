"""Ros2ControlAdapter: a Driver (paper §4.1 "Drivers", §4.2 "Application") that couples the
constraint-based program to an existing ROS 2 driver, e.g. ros2_control's
joint_state_broadcaster and a JointGroupVelocityController (or position controller, or a
JointTrajectoryController).

* reads ``sensor_msgs/JointState`` on ``joint_states_topic``: joints mapped by name, any order,
  joints it does not drive (a gripper) ignored; hands them on as ``joint_state``
  (``JointPositions(<robot>)``);
* takes the Solver's ``command`` (``JointVelocities(program)``), picks its ``joints`` by name and
  writes to ``command_topic``, in the order of ``joints``, per ``interface``:

  - ``velocity``: ``std_msgs/Float64MultiArray`` of velocities (``<controller>/commands``);
  - ``position``: ``std_msgs/Float64MultiArray`` of positions, integrating the velocities from
    the measured positions;
  - ``trajectory``: ``trajectory_msgs/JointTrajectory``, one point ``horizon`` seconds ahead.

A joint state that lacks one of its ``joints`` (a driver that names them otherwise, a position
list shorter than the names) is not a measurement: the first one raises
``e_<robot>_joints_missing`` naming the joints missing and those the driver has (the watchdog
then finds the driver silent).

On disengage and in Safety it commands zero velocity (velocity) or holds the measured position.
In Safety it keeps reporting what the driver measures (as a simulated robot does), so that the
watchdog Monitors can tell whether a silent driver came back before a recovery.

What it reports is what the driver measured, a non-finite position too (the watchdog's
``nonfinite`` Monitor puts the program in Safety); what it commands never is: a position or
trajectory command starts from each joint's last finite position, and none is sent before every
joint had one.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from builtin_interfaces.msg import Duration
from pydantic import Field
from rclpy.publisher import Publisher
from rclpy.subscription import Subscription
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from itasc_core.communication.event_names import JOINTS_MISSING, event
from itasc_core.communication.ports import PortSpec
from itasc_core.communication.qos import OUTSIDE_QOS
from itasc_core.communication.samples import JointSample
from itasc_core.computation.functional_entity import FunctionalEntity
from itasc_core.computation.parameters import ParameterModel, TopicName

from .ports import driver_ports

__all__ = ['Ros2ControlAdapter']


class Ros2ControlAdapter(FunctionalEntity):
    """joint_states in; Float64MultiArray or JointTrajectory commands out, joints by name."""
    _state_sub: Subscription | None = None
    _publisher: Publisher | None = None

    class Parameters(ParameterModel):
        robot: str = Field(default='robot', frozen=True)
        """The robot it drives."""
        joints: list[str] = Field(min_length=1, frozen=True)
        """The controller's joints, in the order its commands have them."""
        joint_states_topic: TopicName = '/joint_states'
        """Where the driver publishes ``sensor_msgs/JointState``."""
        command_topic: TopicName = '/velocity_controller/commands'
        """Where commands go."""
        interface: Literal['velocity', 'position', 'trajectory'] = 'velocity'
        """What the controller takes: velocities or positions (``std_msgs/Float64MultiArray``), or a
        ``trajectory_msgs/JointTrajectory``."""
        horizon: float = Field(default=0.1, gt=0)
        """How far ahead a position or trajectory command reaches [s]."""

    @classmethod
    def port_specs(cls, params: Parameters) -> list[PortSpec]:
        return driver_ports(params.robot)

    def configure(self, params: Parameters) -> None:
        """Topics and interface may change while it runs: what the driver measured stays while its
        joint states still come from the same topic."""
        self.joints = list(params.joints)
        self.robot, self.joint_states_topic = params.robot, params.joint_states_topic
        msg_type = JointTrajectory if params.interface == 'trajectory' else Float64MultiArray
        state_sub = self.subscription_for(self._state_sub, JointState, params.joint_states_topic, self._on_state,
                                           OUTSIDE_QOS)
        try:
            publisher = self.publisher_for(self._publisher, msg_type, params.command_topic, 10)
        except BaseException:
            self.let_go(state_sub, kept=self._state_sub)
            raise
        self.let_go(self._publisher, kept=publisher)
        self.let_go(self._state_sub, kept=state_sub)
        if state_sub is not self._state_sub:
            self.measured: np.ndarray | None = None
            #: Each joint's last finite measured position (None until every joint had one).
            self.held: np.ndarray | None = None
            self._fresh = False
            self._missing_reported = False
        self._state_sub, self._publisher = state_sub, publisher
        self.interface = params.interface
        self.horizon = params.horizon
        self._target: np.ndarray | None = None
        self._last_t: float | None = None

    def _on_state(self, msg: JointState) -> None:
        by_name = dict(zip(msg.name, msg.position))
        if all(j in by_name for j in self.joints):
            self.measured = measured = np.array([by_name[j] for j in self.joints], dtype=float)
            self._fresh = True
            finite = np.isfinite(measured)
            if finite.all():
                self.held = measured
            elif self.held is not None:
                self.held = np.where(finite, measured, self.held)
        elif not self._missing_reported:
            self._missing_reported = True
            missing = ', '.join(j for j in self.joints if j not in by_name)
            self.raise_event(event(self.robot, JOINTS_MISSING),
                             detail=f'{missing} not in {self.joint_states_topic} (it has: {", ".join(by_name)})')

    def update(self, t: float) -> None:
        dt = 0.0 if self._last_t is None else max(t - self._last_t, 0.0)
        self._last_t = t
        if self.measured is None:
            return  # nothing to report, nothing to command before the driver reported
        self._report()
        command = self.inputs['command'].latest
        velocity = np.zeros(len(self.joints))
        if command is not None:
            by_name = dict(zip(command.name, command.velocity))
            velocity = np.array([by_name.get(j, 0.0) for j in self.joints], dtype=float)
        self._send(np.where(np.isfinite(velocity), velocity, 0.0), dt)

    def _report(self) -> None:
        if self._fresh and self.measured is not None:  # only what the driver reported: silence shows as stale
            self._fresh = False
            self.outputs['joint_state'].write(JointSample(self.get_clock().now().nanoseconds * 1e-9,
                                                          tuple(self.joints), self.measured))

    def _send(self, velocity: np.ndarray, dt: float) -> None:
        if self.interface == 'velocity':
            self._publisher.publish(Float64MultiArray(data=velocity.tolist()))
            return
        if self.held is None:
            return  # no position to start from: the controller holds its last command
        if self._target is None or not velocity.any():
            self._target = self.held.copy()
        if self.interface == 'position':
            self._target = self._target + velocity * dt
            self._publisher.publish(Float64MultiArray(data=self._target.tolist()))
            return
        seconds = int(self.horizon)
        point = JointTrajectoryPoint(positions=(self.held + velocity * self.horizon).tolist(),
                                     velocities=velocity.tolist(),
                                     time_from_start=Duration(sec=seconds, nanosec=int((self.horizon - seconds) * 1e9)))
        self._publisher.publish(JointTrajectory(joint_names=self.joints, points=[point]))

    def disengage(self) -> None:
        if self.measured is not None:
            self._target = None
            self._send(np.zeros(len(self.joints)), 0.0)

    def safe(self) -> None:
        """Safety, at every tick: report what the driver measures, command it to hold."""
        if self.measured is not None:
            self._report()
        self.disengage()
