"""A stand-in for a gripper node, in a process of its own (README "Operating a running
application"): publishes ``std_msgs/msg/Bool`` "object grasped" on ``--topic``, false at 10 Hz for
``--false-for`` seconds once someone listens, then true at 10 Hz until ended. Prints
``true from <time.time()>`` when it starts saying true, so that a test can compare it with a
recording's send times (both are the system clock)."""

from __future__ import annotations

import argparse
import time

import rclpy
from std_msgs.msg import Bool

from itasc_core.communication.dds import configure_dds


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument('--topic', default='/gripper/object_grasped')
    parser.add_argument('--false-for', type=float, default=1.5)
    args = parser.parse_args()
    configure_dds()
    rclpy.init()
    node = rclpy.create_node('gripper')
    publisher = node.create_publisher(Bool, args.topic, 10)
    while publisher.get_subscription_count() == 0:
        time.sleep(0.05)
    end_false = time.monotonic() + args.false_for
    said_true = False
    try:
        while True:
            grasped = time.monotonic() >= end_false
            if grasped and not said_true:
                print(f'true from {time.time():.6f}', flush=True)
                said_true = True
            publisher.publish(Bool(data=grasped))
            time.sleep(0.1)
    except KeyboardInterrupt:
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    main()
