"""A stand-in for an existing ROS 2 driver that speaks only standard messages, as ros2_control's
joint_state_broadcaster and a JointGroupVelocityController (or JointGroupPositionController, or
JointTrajectoryController) do: it publishes ``sensor_msgs/JointState`` on ``joint_states`` — joints
in a different order than the controller's, plus one joint nobody controls (a gripper finger) — and
follows what it receives:

* ``--interface velocity``: ``std_msgs/Float64MultiArray`` on ``/<controller>/commands``,
  velocities in the controller's joint order, integrated;
* ``--interface position``: the same with positions, taken at once;
* ``--interface trajectory``: ``trajectory_msgs/JointTrajectory`` on
  ``/<controller>/joint_trajectory``, joints by name (a subset is allowed, unknown joints reject
  the whole message, as the JointTrajectoryController does); it moves at constant velocity to the
  first point, reaching it ``time_from_start`` after receipt, and stays there.

``--state-qos sensor_data``: joint states best effort, as many drivers and simulators publish them.
``--command-topic``: where the commands come instead (a controller whose topic was remapped).

Used to test the Ros2ControlAdapter Driver (paper §4.2: the same program on other hardware by
swapping the Driver). Run: ``fake_ros2_control [--controller velocity_controller] [--rate 200]``.
"""

from __future__ import annotations

import argparse
import time

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.qos import QoSProfile, qos_profile_sensor_data
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray
from trajectory_msgs.msg import JointTrajectory

from itasc_core.communication.dds import configure_dds

__all__ = ['FakeRos2Control', 'main']

PANDA = [f'panda_joint{i}' for i in range(1, 8)]
PANDA_READY = [0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785]


class FakeRos2Control(Node):
    """joint_state_broadcaster + a joint group controller, kinematically simulated."""

    def __init__(self, *, joints: list[str], initial: list[float], extra_joint: str, controller: str,
                 interface: str, rate: float, joint_states: str, state_qos: QoSProfile | int = 10,
                 command_topic: str | None = None) -> None:
        super().__init__('fake_ros2_control')
        self.joints = list(joints)
        self.positions = dict(zip(joints, initial))
        self.velocities = dict.fromkeys(joints, 0.0)
        self.extra_joint = extra_joint
        self.interface = interface
        self.commands_received = 0
        self._publisher = self.create_publisher(JointState, joint_states, state_qos)
        if interface == 'trajectory':
            self.create_subscription(JointTrajectory, command_topic or f'/{controller}/joint_trajectory',
                                     self._on_trajectory, 10)
        else:
            self.create_subscription(Float64MultiArray, command_topic or f'/{controller}/commands',
                                     self._on_command, 10)
        self._arrival: float | None = None  # trajectory: when the point is reached
        self._last = time.monotonic()
        self.create_timer(1.0 / rate, self._step)

    def _on_command(self, msg: Float64MultiArray) -> None:
        if len(msg.data) != len(self.joints):
            self.get_logger().error(f'command of {len(msg.data)} values for {len(self.joints)} joints ignored')
            return
        self.commands_received += 1
        if self.interface == 'velocity':
            self.velocities = dict(zip(self.joints, msg.data))
        else:
            self.positions = dict(zip(self.joints, msg.data))

    def _on_trajectory(self, msg: JointTrajectory) -> None:
        unknown = sorted(set(msg.joint_names) - set(self.joints))
        if unknown or not msg.points or len(msg.points[0].positions) != len(msg.joint_names):
            self.get_logger().error(f'trajectory for joints {list(msg.joint_names)} rejected (unknown: {unknown})')
            return
        self.commands_received += 1
        point = msg.points[0]
        duration = max(point.time_from_start.sec + 1e-9 * point.time_from_start.nanosec, 1e-3)
        self.velocities = dict.fromkeys(self.joints, 0.0)
        for joint, target in zip(msg.joint_names, point.positions):
            self.velocities[joint] = (target - self.positions[joint]) / duration
        self._arrival = time.monotonic() + duration

    def _step(self) -> None:
        now = time.monotonic()
        dt, self._last = now - self._last, now
        if self.interface == 'trajectory' and self._arrival is not None:
            dt = min(dt, max(self._arrival - (now - dt), 0.0))
            if now >= self._arrival:
                self._arrival = None
        if self.interface in ('velocity', 'trajectory'):
            for joint, velocity in self.velocities.items():
                self.positions[joint] += velocity * dt
            if self.interface == 'trajectory' and self._arrival is None:
                self.velocities = dict.fromkeys(self.joints, 0.0)
        order = list(reversed(self.joints))  # not the controller's order
        msg = JointState(name=order + [self.extra_joint],
                         position=[self.positions[j] for j in order] + [0.04],
                         velocity=[self.velocities[j] for j in order] + [0.0])
        msg.header.stamp = self.get_clock().now().to_msg()
        self._publisher.publish(msg)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--joints', default=','.join(PANDA))
    parser.add_argument('--initial', default=','.join(map(str, PANDA_READY)))
    parser.add_argument('--extra-joint', default='panda_finger_joint1')
    parser.add_argument('--controller', default='velocity_controller')
    parser.add_argument('--interface', default='velocity', choices=('velocity', 'position', 'trajectory'))
    parser.add_argument('--rate', type=float, default=200.0)
    parser.add_argument('--joint-states', default='/joint_states')
    parser.add_argument('--command-topic', default=None,
                        help='where the commands come '
                             '(default: /<controller>/commands, or /<controller>/joint_trajectory)')
    parser.add_argument('--state-qos', default='reliable', choices=('reliable', 'sensor_data'),
                        help="the joint states' QoS: reliable (joint_state_broadcaster's) or sensor_data "
                             '(best effort, as many drivers and simulators publish)')
    args = parser.parse_args(argv)
    joints = args.joints.split(',')
    initial = [float(v) for v in args.initial.split(',')]
    if len(initial) != len(joints):
        parser.error(f'{len(initial)} initial positions for {len(joints)} joints')
    configure_dds()
    rclpy.init()
    node = FakeRos2Control(joints=joints, initial=initial, extra_joint=args.extra_joint,
                           controller=args.controller, interface=args.interface, rate=args.rate,
                           joint_states=args.joint_states,
                           state_qos=qos_profile_sensor_data if args.state_qos == 'sensor_data' else 10,
                           command_topic=args.command_topic)
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
