"""SimulatedRobot: a Driver (paper §4.1 "Drivers") that simulates a robot kinematically.

Every tick of the program it integrates the commanded joint velocities over the time since the
previous tick (so at the program rate) on the robot's kinematic model (a mobile base moves in
its own frame, as the Solver commands it), within the joint velocity and position limits (the
URDF's, or those given as ``lower``/``upper``/``velocity_limit``, one value per joint, e.g. the
application model's overrides), and publishes the joint state (``sensor_msgs/JointState`` with names, positions and the
applied velocities), also on ``<composite namespace>/<robot>/joint_states`` for
robot_state_publisher and RViz. Input ``command``: the Solver's ``JointVelocities(program)``, from which it
takes its own joints by name; output ``joint_state``: ``JointPositions(<robot>)``.

``main()`` runs one standalone, as its own process, on plain topics.
"""

from __future__ import annotations

import argparse
import math
import time
from typing import Any

import numpy as np
import rclpy
from rclpy.executors import ExternalShutdownException
from sensor_msgs.msg import JointState

from itasc_core.communication.dds import configure_dds
from itasc_core.communication.ports import PortSpec
from itasc_core.computation.functional_entity import FunctionalEntity
from itasc_core.entity import CompositeContext
from itasc_core.itasc.robot import Robot

from .ports import driver_ports

__all__ = ['SimulatedRobot', 'main']


class SimulatedRobot(FunctionalEntity):
    """Integrates commanded joint velocities; publishes the joint state."""

    PARAMETERS = {
        'robot': 'robot',
        'urdf': '',
        'base': 'fixed',
        'initial_names': [''],
        'initial_positions': [0.0],
        # one value per joint of the robot, or the single default: the URDF's limits
        'lower': [math.nan],
        'upper': [math.nan],
        'velocity_limit': [math.nan],
    }

    @classmethod
    def port_specs(cls, params: dict[str, Any]) -> list[PortSpec]:
        return driver_ports(params['robot'])

    def configure(self, params: dict[str, Any]) -> None:
        if getattr(self, 'robot', None) is not None:
            return  # the simulated world keeps its state across re-configuration
        self.robot = Robot(params['robot'], params['urdf'], base=params['base'])
        for key in ('lower', 'upper', 'velocity_limit'):
            if len(params[key]) == len(getattr(self.robot, key)):
                getattr(self.robot, key)[:] = params[key]
        self.robot.set_positions([n for n in params['initial_names'] if n], params['initial_positions'])
        self.robot.set_position_vector(self._within_limits(self.robot.positions))
        self.velocity = np.zeros(self.robot.nv)
        self._last_t: float | None = None
        # the conventional topic robot_state_publisher and RViz read, in the robot's namespace
        self._joint_states = self.create_publisher(
            JointState, f"{self.composite.namespace.rstrip('/')}/{params['robot']}/joint_states", 10)

    def _within_limits(self, positions: np.ndarray) -> np.ndarray:
        return np.clip(positions, self.robot.lower, self.robot.upper)

    def update(self, t: float) -> None:
        dt = 0.0 if self._last_t is None else max(t - self._last_t, 0.0)
        self._last_t = t
        command = self.inputs['command'].latest
        velocity = np.zeros(self.robot.nv)
        if command is not None:
            by_name = dict(zip(command.name, command.velocity))
            velocity = np.array([by_name.get(n, 0.0) for n in self.robot.joint_names], dtype=float)
            velocity = np.where(np.isfinite(velocity), velocity, 0.0)
            velocity = np.clip(velocity, -self.robot.velocity_limit, self.robot.velocity_limit)
        if dt > 0.0:
            self.robot.integrate(velocity, dt)
            self.robot.set_position_vector(self._within_limits(self.robot.positions))
        self.velocity = velocity
        self._publish()

    def _publish(self) -> None:
        msg = JointState(name=list(self.robot.joint_names), position=self.robot.positions.tolist(),
                         velocity=self.velocity.tolist())
        msg.header.stamp = self.get_clock().now().to_msg()
        self.outputs['joint_state'].write(msg)
        self._joint_states.publish(msg)

    def disengage(self) -> None:
        self.velocity = np.zeros(self.robot.nv)
        self._publish()


def main(argv: list[str] | None = None) -> int:
    """``simulated_robot --urdf panda.urdf [--robot panda] [--rate 100] [--initial j=v,...]``:
    publishes on ``<namespace>/<robot>/joint_state``, takes velocities (JointState) from
    ``--command-topic``."""
    parser = argparse.ArgumentParser(description='A kinematically simulated robot (iTaSC Driver).')
    parser.add_argument('--urdf', required=True)
    parser.add_argument('--robot', default='robot')
    parser.add_argument('--base', default='fixed', choices=('fixed', 'planar', 'free_flyer'))
    parser.add_argument('--rate', type=float, default=100.0)
    parser.add_argument('--initial', default='', help='initial positions: joint=value,joint=value')
    parser.add_argument('--namespace', default='/sim')
    parser.add_argument('--command-topic', default='/sim/command')
    args = parser.parse_args(argv)
    initial = dict(item.split('=') for item in args.initial.split(',') if item)
    configure_dds()
    rclpy.init()
    node = SimulatedRobot(args.robot, composite=CompositeContext(name='sim', namespace=args.namespace),
                          parameters={'robot': args.robot, 'urdf': args.urdf, 'base': args.base,
                                      'initial_names': list(initial) or [''],
                                      'initial_positions': [float(v) for v in initial.values()] or [0.0]})
    node.inputs['command'].connect(args.command_topic)
    start = time.monotonic()
    node.create_timer(1.0 / args.rate, lambda: node.update(time.monotonic() - start))
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
