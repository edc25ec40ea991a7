"""Our DDS settings (itasc_core.communication.dds): processes talk over UDP only, nothing in shared
memory that a killed process could leave locked, and discovery still works between processes."""

from __future__ import annotations

import os
import sys
import textwrap
import time

import pytest
from processes import Spawned

_PEER = textwrap.dedent('''
    import sys, time
    from itasc_core.communication.dds import configure_dds
    configure_dds()
    import rclpy
    from std_msgs.msg import String
    rclpy.init()
    node = rclpy.create_node('peer_' + sys.argv[1])
    if sys.argv[1] == 'talker':
        pub = node.create_publisher(String, '/dds_test/chatter', 10)
        while True:
            pub.publish(String(data='hello'))
            rclpy.spin_once(node, timeout_sec=0.05)
    heard = []
    node.create_subscription(String, '/dds_test/chatter', heard.append, 10)
    end = time.monotonic() + 20
    while not heard and time.monotonic() < end:
        rclpy.spin_once(node, timeout_sec=0.05)
    print('heard' if heard else 'nothing', flush=True)
    time.sleep(1.0)  # keep the participant alive while the test looks at /dev/shm
''')


def _fastdds_segments() -> set[str]:
    return {name for name in os.listdir('/dev/shm') if name.startswith('fastrtps_')}


@pytest.mark.skipif(not os.path.isdir('/dev/shm'), reason='needs /dev/shm (Linux)')
def test_processes_discover_each_other_without_shared_memory():
    before = _fastdds_segments()
    with Spawned([sys.executable, '-c', _PEER, 'talker']) as talker, \
            Spawned([sys.executable, '-c', _PEER, 'listener']) as listener:
        listener.wait_for_line('heard', timeout=30)
        created = _fastdds_segments() - before
        talker.kill()  # SIGKILL, as a crashed driver would end
        assert listener.finish(timeout=30) == 0, listener.output()
    assert not created, f'Fast DDS shared-memory segments were created: {sorted(created)}'


def test_a_process_whose_teardown_hangs_still_ends():
    """end_process_within: the deadline holds even while the main thread is stuck outside Python."""
    hang = ('import time; from itasc_core.composition.deployment import end_process_within; '
            'end_process_within(1.0); time.sleep(60)')
    with Spawned([sys.executable, '-c', hang]) as process:
        started = time.monotonic()
        code = process.finish(timeout=20)
        took = time.monotonic() - started
    assert code == 1 and took < 10, (code, took)
    assert process.err.startswith('Timeout (0:00:01)!'), process.err  # with every thread's stack
