"""Suite-wide setup. Runs before any test module, hence before rclpy is imported anywhere.

Each pytest process (the main one, or each pytest-xdist worker) gets a ROS_DOMAIN_ID no other
test process on this machine holds, so that concurrently running tests, and concurrent test runs,
do not discover each other's nodes and topics. Subprocesses started by tests inherit it.

Every test is also checked for processes it left running (see :func:`no_process_left_running`).
"""
import fcntl
import os
import pathlib
import signal
import sys
import tempfile
import time

import pytest

REPO_ROOT = pathlib.Path(__file__).resolve().parent.parent

# Test helpers (``processes``) and the Functional Entity kinds of the runtime tests (``test_support.probes:...``).
sys.path.insert(0, str(REPO_ROOT / 'test' / 'support'))
from processes import started_here  # noqa: E402


def _test_domain_id() -> int:
    """A ROS domain id in 1..101 (0, the default domain, is never used) that no other test process
    on this machine holds: each id is claimed by an exclusive lock on a file of its own, kept for
    this process's life (the kernel drops it when the process ends, however it ends). Several test
    runs at once (pytest-xdist workers, two checkouts, CI and a developer) would otherwise share a
    domain one time in a hundred and hear each other's nodes.

    The search starts at an id derived from the pid, so that concurrent starts rarely contend."""
    locks = pathlib.Path(tempfile.gettempdir()) / 'itasc_test_domains'
    locks.mkdir(exist_ok=True)
    start = os.getpid() % 101
    for offset in range(101):
        domain = 1 + (start + offset) % 101
        handle = open(locks / f'{domain}.lock', 'w')
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            handle.close()
            continue
        _DOMAIN_LOCK.append(handle)
        return domain
    raise RuntimeError(f'all 101 test domains are held by other test processes (locks in {locks})')


_DOMAIN_LOCK: list = []  # the open lock file of this process's domain

os.environ['ROS_DOMAIN_ID'] = str(_test_domain_id())
# Keep discovery on this machine even when the suite runs outside scripts/env.sh, with our Fast DDS
# profile, as every executable of ours does (itasc_core.communication.dds).
os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
from itasc_core.communication.dds import configure_dds  # noqa: E402

configure_dds()


# Marks every process this pytest process starts, directly or not (see processes.started_here).
os.environ['ITASC_TEST_SESSION'] = str(os.getpid())


@pytest.fixture(autouse=True)
def no_process_left_running():
    """A test must not leave processes behind: they would disturb later tests and hold the run's
    output pipe open after pytest ends. Leftovers get a few seconds to end, are then killed, and
    the test errors, naming them."""
    yield
    if not os.path.isdir('/proc'):
        return
    deadline = time.monotonic() + 10.0
    while (left := started_here()) and time.monotonic() < deadline:
        time.sleep(0.1)
    for pid in left:
        try:
            os.kill(pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
    assert not left, f'processes left running by this test (killed now): {left}'


def _dds_participants() -> int:
    """DDS participants alive in this process: Fast DDS runs one event thread ``dds.ev.<id>`` each."""
    count = 0
    for task in os.listdir('/proc/self/task'):
        try:
            with open(f'/proc/self/task/{task}/comm') as comm:
                count += comm.read().startswith('dds.ev.')
        except OSError:
            continue
    return count


@pytest.fixture(autouse=True)
def no_dds_participant_left():
    """A test must destroy every node it created (ros_teardown.destroy_all): a context's DDS
    participant lives as long as one of its nodes, and participants left over in this process
    can deadlock Fast DDS when a later test deletes its own (see ros_teardown)."""
    before = _dds_participants() if os.path.isdir('/proc/self/task') else 0
    yield
    if os.path.isdir('/proc/self/task'):
        left = _dds_participants() - before
        assert left <= 0, f'this test left {left} DDS participant(s) alive: nodes not destroyed'


@pytest.fixture
def context():
    """A ROS context of the test's own, shut down after it (its nodes are the test's to destroy)."""
    import rclpy
    from rclpy.context import Context

    ctx = Context()
    rclpy.init(context=ctx)
    yield ctx
    rclpy.try_shutdown(context=ctx)


@pytest.fixture(scope='session')
def repo_root() -> pathlib.Path:
    """Absolute path of the repository root."""
    return REPO_ROOT
