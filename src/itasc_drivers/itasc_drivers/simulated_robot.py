"""SimulatedRobot: a Driver (paper §4.1 "Drivers") that simulates a robot kinematically.

Every tick of the program it integrates the commanded joint velocities over the time since the
previous tick (so at the program rate) on the robot's kinematic model (a mobile base moves in
its own frame, as the Solver commands it), within the joint velocity and position limits (the
URDF's, or those given as ``lower``/``upper``/``velocity_limit``, one value per joint, e.g. the
application model's overrides), and publishes the joint state (``sensor_msgs/JointState`` with names, positions and the
applied velocities), also on ``<composite namespace>/<robot>/joint_states`` for
robot_state_publisher and RViz (an output port: published while someone listens there). Input ``command``: the Solver's
``JointVelocities(program)``, from which it
takes its own joints by name; output ``joint_state``: ``JointPositions(<robot>)``.

``main()`` runs one standalone, as its own process, on plain topics.
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace
from typing import Literal

import numpy as np
import rclpy
from pydantic import Field, field_validator
from rclpy.executors import ExternalShutdownException

from itasc_core.communication.dds import configure_dds
from itasc_core.communication.ports import OutputPort, PortSpec
from itasc_core.communication.samples import JointSample
from itasc_core.computation.functional_entity import FunctionalEntity
from itasc_core.computation.parameters import ParameterModel
from itasc_core.entity import CompositeContext
from itasc_core.finite import all_finite
from itasc_core.itasc.robot import Robot

from .ports import driver_ports

__all__ = ['SimulatedRobot', 'main']

#: The limits a model or a parameter change may give, one value per joint (none: the URDF's).
_LIMITS = ('lower', 'upper', 'velocity_limit')


class SimulatedRobot(FunctionalEntity):
    """Integrates commanded joint velocities; publishes the joint state."""

    class Parameters(ParameterModel):
        robot: str = Field(default='robot', frozen=True)
        """The robot's name."""
        urdf: str = Field(default='', frozen=True)
        """Its URDF file (absolute path)."""
        base: Literal['fixed', 'planar', 'free_flyer'] = Field(default='fixed', frozen=True)
        """Its base: fixed, or a mobile base's joints."""
        initial: dict[str, float] = Field(default_factory=dict, frozen=True)
        """Initial joint positions by joint name [rad or m] (the others: 0, within the limits)."""
        lower: list[float] = Field(default_factory=list)
        """Lowest position per joint [rad or m]; none: the URDF's."""
        upper: list[float] = Field(default_factory=list)
        """Highest position per joint; none: the URDF's."""
        velocity_limit: list[float] = Field(default_factory=list)
        """Largest speed per joint (> 0, inf: none); none given: the URDF's."""

        @field_validator('velocity_limit')
        @classmethod
        def _positive(cls, value: list[float]) -> list[float]:
            if not all(v > 0.0 for v in value):
                raise ValueError('every velocity limit must be > 0 (a limit of 0 or below would move the joint '
                                 'whatever is commanded, or never)')
            return value

    @classmethod
    def port_specs(cls, params: Parameters) -> list[PortSpec]:
        return driver_ports(params.robot)

    def configure(self, params: Parameters) -> None:
        """The robot (its name, URDF, base and start, read-only) is made once; the limits are
        applied at every change, the simulated world keeping its state."""
        robot: Robot | None = getattr(self, 'robot', None)
        first = robot is None
        if robot is None:
            robot = Robot(params.robot, params.urdf, base=params.base)
            self._urdf_limits = {key: getattr(robot, key).copy() for key in _LIMITS}
        limits = {}
        for key in _LIMITS:
            given, urdf = getattr(params, key), self._urdf_limits[key]
            if given and len(given) != len(urdf):
                raise ValueError(f'{key} has {len(given)} values for the {len(urdf)} joints of {params.robot}')
            limits[key] = np.array(given, dtype=float) if given else urdf
        self._check_limits(robot, limits, moving=not first)
        for key, values in limits.items():
            getattr(robot, key)[:] = values
        self._lowest_velocity = -robot.velocity_limit
        if not first:
            return
        self.robot = robot
        self.robot.set_positions(list(params.initial), list(params.initial.values()))
        self.robot.set_position_vector(self._within_limits(self.robot.positions))
        self.velocity = np.zeros(self.robot.nv)
        self._last_t: float | None = None
        self._names = tuple(self.robot.joint_names)
        self._order: tuple[tuple[str, ...], np.ndarray] = ((), np.zeros(0, dtype=int))
        self._stamp_clock = self.get_clock()
        # the conventional topic robot_state_publisher and RViz read, in the robot's namespace: an
        # output (not one the model connects) that a recorder in this process taps
        spec = next(s for s in self.port_specs(params) if s.name == 'joint_state')
        self._joint_states = OutputPort(self, replace(spec, name='joint_states').with_id(
            f"{self.composite.namespace.rstrip('/')}/{params.robot}/joint_states"))

    @staticmethod
    def _check_limits(robot: Robot, limits: dict[str, np.ndarray], *, moving: bool) -> None:
        """Limits that contradict each other, or, while it runs, that leave a joint where it is
        outside (the robot would jump to the limit in one tick), are refused."""
        names = robot.joint_names
        crossed = [n for n, lo, hi in zip(names, limits['lower'], limits['upper']) if lo > hi]
        if crossed:
            raise ValueError(f'lower is above upper for {", ".join(crossed)}')
        if moving:
            outside = [f'{n} at {q:.4g} (limits [{lo:.4g}, {hi:.4g}])' for n, q, lo, hi
                       in zip(names, robot.positions, limits['lower'], limits['upper']) if not lo <= q <= hi]
            if outside:
                raise ValueError(f'the robot is outside the new limits: {", ".join(outside)}')

    def _within_limits(self, positions: np.ndarray) -> np.ndarray:
        return np.minimum(np.maximum(positions, self.robot.lower), self.robot.upper)

    def update(self, t: float) -> None:
        dt = 0.0 if self._last_t is None else max(t - self._last_t, 0.0)
        self._last_t = t
        command = self.inputs['command'].latest
        robot = self.robot
        if command is None:
            velocity = np.zeros(robot.nv)
        else:
            velocity = self._own(command)
            if not all_finite(velocity):
                velocity = np.where(np.isfinite(velocity), velocity, 0.0)
            velocity = np.minimum(np.maximum(velocity, self._lowest_velocity), robot.velocity_limit)
        if dt > 0.0:
            robot.integrate(velocity, dt)
            positions = self._within_limits(robot.positions)
            robot.set_position_vector(positions)
        else:
            positions = robot.positions
        self.velocity = velocity
        self._publish(positions)

    def _own(self, command: JointSample) -> np.ndarray:
        """This robot's joint velocities in a command (by name; joints it does not name: 0)."""
        if command.name == self._names and len(command.velocity) == len(command.name):
            return command.velocity  # the Solver's order is this robot's (one robot): no reordering
        if command.name != self._order[0]:
            where = {n: i for i, n in enumerate(command.name)}
            # a missing joint reads the appended 0
            self._order = (command.name, np.array([where.get(n, len(command.name)) for n in self._names], dtype=int))
        velocity = command.velocity
        if len(velocity) != len(command.name):
            return np.zeros(self.robot.nv)
        return np.append(velocity, 0.0)[self._order[1]]

    def _now(self) -> float:
        """The node's clock: the system's, read directly, unless the node uses simulated time (its
        ``use_sim_time``, which rclpy's TimeSource follows: a parameter lookup, ~0.3 us, where
        asking the clock's handle took ~1 us, 1.9 % of a 1 kHz tick in py-spy)."""
        if not self.get_parameter('use_sim_time').value:
            return time.time()
        return self._stamp_clock.now().nanoseconds * 1e-9

    def _publish(self, positions: np.ndarray | None = None) -> None:
        """The joint state: ``positions`` (the robot's, if not given: a copy the sample keeps)."""
        if positions is None:
            positions = self.robot.positions
        sample = JointSample(self._now(), self._names, positions, velocity=self.velocity)
        self.outputs['joint_state'].write(sample)
        self._joint_states.write(sample)

    def disengage(self) -> None:
        self.velocity = np.zeros(self.robot.nv)
        self._publish()

    def destroy_node(self) -> None:
        if getattr(self, '_joint_states', None) is not None:
            self._joint_states.destroy()
        super().destroy_node()


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
                                      'initial': {k: float(v) for k, v in initial.items()}})
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
