"""What a user would write instead of an iTaSC application (issue #9): one rclpy node that reads
``joint_states``, runs the same Tasks and the same QP (:class:`fused.FusedProgram`, no entities,
ports, events or life-cycle) on a timer and publishes the joint velocity command; its Driver, the
simulated robot of ``itasc_drivers`` running standalone, lives in a process of its own as a real
driver would. The cycle time is the timer callback's: read the newest joint state, compute,
publish. Every robot of the program has its simulated driver (a program of several robots reads
all their joint states), its joints starting where the application's Driver starts them.

    python bench/handwritten.py APP --rate HZ --seconds S    # prints RESULT {json}
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import signal
import subprocess
import sys
import time

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))

__all__ = ['main']


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('app')
    parser.add_argument('--rate', type=float, required=True)
    parser.add_argument('--seconds', type=float, default=10.0)
    parser.add_argument('--settle', type=float, default=1.0, help='seconds before measuring')
    args = parser.parse_args(argv)

    from itasc_core.communication.dds import configure_dds
    configure_dds()
    import rclpy
    from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import JointState

    from fused import FusedProgram
    from itasc_bringup.apps import resolve_app
    from itasc_bringup.model import load_application
    from itasc_bringup.model.checks import driven_robot
    from stand_ins import initial_positions

    app = load_application(resolve_app(args.app))
    program = FusedProgram.of(app)
    drivers = {d.robot: d for d in app.drivers}
    sims = []
    for robot in app.program.robots:
        initial = initial_positions(drivers.get(robot.name), driven_robot(robot, args.rate))
        sims.append(subprocess.Popen(
            [sys.executable, '-m', 'itasc_drivers.simulated_robot', '--urdf', robot.urdf, '--robot', robot.name,
             '--base', robot.base, '--rate', str(args.rate), '--namespace', '/handwritten_sim',
             '--command-topic', '/handwritten/command',
             '--initial', ','.join(f'{k}={v!r}' for k, v in initial.items())],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
    rclpy.init()
    node = rclpy.create_node('handwritten')
    qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1, reliability=ReliabilityPolicy.RELIABLE)
    latest: dict[str, JointState] = {}  # the newest joint state of each robot
    for robot in app.program.robots:
        node.create_subscription(JointState, f'/handwritten_sim/{robot.name}/joint_state',
                                 lambda msg, name=robot.name: latest.__setitem__(name, msg), qos)
    robots = len(app.program.robots)
    publisher = node.create_publisher(JointState, '/handwritten/command', qos)
    names = program.joint_names
    index = {n: i for i, n in enumerate(names)}
    cycles: list[float] = []
    stamps: list[float] = []
    dt = 1.0 / args.rate
    start = time.monotonic()

    def cycle() -> None:
        began = time.monotonic()
        if len(latest) < robots:
            return
        q = program.initial.copy()
        for msg in latest.values():
            for name, value in zip(msg.name, msg.position):
                i = index.get(name)
                if i is not None:
                    q[i] = value
        qdot = program.step(q, began - start, dt)
        out = JointState(name=names, velocity=qdot.tolist())
        out.header.stamp = node.get_clock().now().to_msg()
        publisher.publish(out)
        cycles.append(time.monotonic() - began)
        stamps.append(began)

    node.create_timer(dt, cycle)
    from itasc_core.composition.deployment import make_executor
    executor = make_executor()
    executor.add_node(node)
    code = 1
    try:
        deadline = time.monotonic() + 30.0
        while len(latest) < robots and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.05)
        if len(latest) < robots:
            silent = [r.name for r in app.program.robots if r.name not in latest]
            print(f'handwritten: the simulated driver of {", ".join(silent)} never published', file=sys.stderr)
            return code
        settle = time.monotonic() + args.settle
        while time.monotonic() < settle:
            executor.spin_once(timeout_sec=0.01)
        cycles.clear()
        stamps.clear()
        end = time.monotonic() + args.seconds
        while time.monotonic() < end:
            executor.spin_once(timeout_sec=0.01)
        us = np.array(cycles) * 1e6
        span = stamps[-1] - stamps[0] if len(stamps) > 1 else 0.0
        print('RESULT ' + json.dumps({
            'cycle_p50_us': float(np.median(us)), 'cycle_p99_us': float(np.percentile(us, 99)),
            'achieved_hz': (len(stamps) - 1) / span if span > 0 else 0.0, 'cycles': len(cycles),
            'tasks': [t.name for t in program.tasks]}), flush=True)
        code = 0
        return code
    finally:
        for sim in sims:
            sim.send_signal(signal.SIGINT)
        for sim in sims:
            try:
                sim.wait(timeout=10)
            except subprocess.TimeoutExpired:
                sim.kill()
        os._exit(code)  # no lingering DDS teardown

if __name__ == '__main__':
    raise SystemExit(main())
