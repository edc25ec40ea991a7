"""What a user would write instead of an iTaSC application (issue #9): one rclpy node that reads
``joint_states``, runs the same Tasks and the same QP (:class:`fused.FusedProgram`, no entities,
ports, events or life-cycle) on a timer and publishes the joint velocity command; its Driver, the
simulated robot of ``itasc_drivers`` running standalone, lives in a process of its own as a real
driver would. The cycle time is the timer callback's: read the newest joint state, compute,
publish.

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

    app = load_application(resolve_app(args.app))
    program = FusedProgram.of(app)
    robot = app.program.robots[0]
    driver = next(d for d in app.drivers if d.robot == robot.name)
    initial = ','.join(f'{k}={v}' for k, v in driver.initial.items())
    sim = subprocess.Popen([sys.executable, '-m', 'itasc_drivers.simulated_robot', '--urdf', robot.urdf,
                            '--robot', robot.name, '--base', robot.base, '--rate', str(args.rate),
                            '--namespace', '/handwritten_sim', '--command-topic', '/handwritten/command',
                            *(['--initial', initial] if initial else [])],
                           stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    rclpy.init()
    node = rclpy.create_node('handwritten')
    qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1, reliability=ReliabilityPolicy.RELIABLE)
    latest: list = [None]
    node.create_subscription(JointState, f'/handwritten_sim/{robot.name}/joint_state',
                             lambda msg: latest.__setitem__(0, msg), qos)
    publisher = node.create_publisher(JointState, '/handwritten/command', qos)
    names = program.joint_names
    index = {n: i for i, n in enumerate(names)}
    cycles: list[float] = []
    stamps: list[float] = []
    dt = 1.0 / args.rate
    start = time.monotonic()

    def cycle() -> None:
        began = time.monotonic()
        msg = latest[0]
        if msg is None:
            return
        q = program.initial.copy()
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
        while latest[0] is None and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.05)
        if latest[0] is None:
            print('handwritten: the simulated driver never published', file=sys.stderr)
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
        sim.send_signal(signal.SIGINT)
        try:
            sim.wait(timeout=10)
        except subprocess.TimeoutExpired:
            sim.kill()
        os._exit(code)  # no lingering DDS teardown

if __name__ == '__main__':
    raise SystemExit(main())
