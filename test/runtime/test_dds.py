"""Our DDS settings (itasc_core.communication.dds): processes talk over UDP only, nothing in shared
memory that a killed process could leave locked, and discovery still works between processes."""

from __future__ import annotations

import os
import subprocess
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


def test_two_test_processes_at_once_never_share_a_domain():
    """Another test process on this machine (a second checkout's suite, an xdist worker) takes a
    domain this one does not hold, even one whose pid would pick the same domain as ours."""
    import subprocess
    from pathlib import Path
    suite = Path(__file__).resolve().parents[1]
    probe = ('import os, sys; os.getpid = lambda: int(sys.argv[2]); sys.path.insert(0, sys.argv[1]); '
             'import conftest; print(os.environ["ROS_DOMAIN_ID"])')
    env = {k: v for k, v in os.environ.items() if k != 'ROS_DOMAIN_ID'}
    other = subprocess.run([sys.executable, '-c', probe, str(suite), str(os.getpid())], capture_output=True,
                           text=True, env=env, timeout=60, check=True)
    assert int(other.stdout.split()[-1]) != int(os.environ['ROS_DOMAIN_ID'])


@pytest.mark.parametrize('value, expected', [('', 0), (' 7', 7), ('232', 232), ('abc', None), ('-1', None),
                                             ('233', None), ('1.5', None), ('\u00b2', None)])
def test_the_ros_domain_id_is_read_as_rcl_reads_it_or_refused_by_name(monkeypatch, value, expected):
    from itasc_core.communication.dds import DdsSettingsError, domain_id
    monkeypatch.setenv('ROS_DOMAIN_ID', value)
    if expected is None:
        with pytest.raises(DdsSettingsError, match=rf"ROS_DOMAIN_ID='{value}' is not a ROS domain id"):
            domain_id()
    else:
        assert domain_id() == expected


_SENDER = textwrap.dedent('''
    import os, sys, time
    from itasc_core.communication.dds import configure_dds, send_from_a_dds_thread
    configure_dds()
    send_from_a_dds_thread()
    import rclpy
    from std_msgs.msg import Float64MultiArray
    rclpy.init()
    node = rclpy.create_node('sender')
    pub = node.create_publisher(Float64MultiArray, '/dds_test/samples', 10)
    node.create_subscription(Float64MultiArray, '/dds_test/samples', lambda _: None, 10)  # a reader
    end = time.monotonic() + 20
    while pub.get_subscription_count() < 1 and time.monotonic() < end:
        time.sleep(0.01)
    time.sleep(0.5)

    def cpu(names):
        total = 0
        for task in os.listdir('/proc/self/task'):
            with open(f'/proc/self/task/{task}/comm') as comm:
                if comm.read().startswith(names):
                    with open(f'/proc/self/task/{task}/stat') as stat:
                        total += sum(int(v) for v in stat.read().rsplit(')', 1)[1].split()[11:13])
        return total
    before = cpu('dds.asyn')
    msg = Float64MultiArray(data=[0.5] * 2000)
    for _ in range(5000):
        pub.publish(msg)
    time.sleep(0.5)
    print(os.environ['RMW_FASTRTPS_PUBLICATION_MODE'], cpu('dds.asyn') - before, flush=True)
''')


@pytest.mark.parametrize('chosen', [None, 'SYNCHRONOUS'])
def test_a_composite_process_sends_from_a_dds_thread_unless_the_user_chose(chosen):
    """``--deploy per-composite``: a composite process's tick hands its samples to a Fast DDS
    thread that sends them (the ``sendto`` was 44 % of the program's tick at 500 Hz), unless
    ``RMW_FASTRTPS_PUBLICATION_MODE`` says otherwise."""
    env = {k: v for k, v in os.environ.items() if k != 'RMW_FASTRTPS_PUBLICATION_MODE'}
    if chosen:
        env['RMW_FASTRTPS_PUBLICATION_MODE'] = chosen
    out = subprocess.run([sys.executable, '-c', _SENDER], capture_output=True, text=True, env=env, timeout=60,
                         check=True).stdout.split()
    mode, sending_ticks = out[-2], int(out[-1])  # clock ticks (1/100 s) the DDS sending threads ran
    assert mode == (chosen or 'ASYNCHRONOUS')
    if chosen:
        assert sending_ticks == 0, out
    else:
        assert sending_ticks > 0, out  # 5000 samples of 16 kB: ~0.1-0.3 s of sending
