"""Suite-wide setup. Runs before any test module, hence before rclpy is imported anywhere.

Each pytest process (the main one, or each pytest-xdist worker) gets its own ROS_DOMAIN_ID
so that concurrently running tests, and concurrent test runs, do not discover each other's
nodes and topics. Subprocesses started by tests inherit it.
"""
import os
import pathlib
import re

import pytest

REPO_ROOT = pathlib.Path(__file__).resolve().parent.parent


def _test_domain_id() -> int:
    """A ROS domain id in 1..101 (0, the default domain, is never used).

    Base: the id of this test run (shared by the xdist workers of one run) or the pid;
    offset: the xdist worker index, so the workers of one run never share a domain.
    """
    worker = os.environ.get('PYTEST_XDIST_WORKER', 'gw0')
    match = re.search(r'(\d+)$', worker)
    index = int(match.group(1)) if match else 0
    run_id = os.environ.get('PYTEST_XDIST_TESTRUNUID')
    base = int(run_id[:8], 16) if run_id else os.getpid()
    return 1 + (base + index) % 101


os.environ['ROS_DOMAIN_ID'] = str(_test_domain_id())
# Our Fast DDS profile (intra-process delivery off, see itasc_core/communication/fastdds.xml).
os.environ.setdefault('FASTRTPS_DEFAULT_PROFILES_FILE',
                      str(REPO_ROOT / 'src/itasc_core/itasc_core/communication/fastdds.xml'))
# Keep discovery on this machine even when the suite runs outside scripts/env.sh.
os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')


@pytest.fixture(scope='session')
def repo_root() -> pathlib.Path:
    """Absolute path of the repository root."""
    return REPO_ROOT

# Functional Entity kinds used by the runtime tests (``test_support.probes:...``).
import sys  # noqa: E402

sys.path.insert(0, str(REPO_ROOT / 'test' / 'support'))
