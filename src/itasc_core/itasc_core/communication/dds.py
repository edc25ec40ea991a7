"""DDS settings the pattern relies on (paper §7.2: no event may be lost; §6: a dead process must
lead the others to Safety, not take them down with it).

Call :func:`configure_dds` before ``rclpy.init``. Unless the user chose a Fast DDS profile of
their own (``FASTRTPS_DEFAULT_PROFILES_FILE``), it points Fast DDS at ours:

- ``fastdds.xml``: intra-process delivery off (a full reader would otherwise drop same-process
  samples silently) and UDPv4 as the only transport. Fast DDS's shared-memory transport is left
  out on purpose: a process killed while it holds a shared-memory port (SIGKILL, a crash) leaves
  the port's lock behind, and the survivors then crash or block inside Fast DDS when they close
  their participant (reproduced with these wheels: a segfault in ``SharedMemChannelResource::
  release``). UDP has no shared state between processes.
- ``fastdds_localhost.xml``: the same, with discovery kept on this machine (unicast to
  127.0.0.1, no multicast). Used for ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``, which
  rmw_fastrtps (Jazzy) would otherwise implement with a shared-memory transport of its own; the
  range becomes ``SYSTEM_DEFAULT`` so that rmw_fastrtps leaves the profile's transports alone.

Both announce their participant every 0.5 s instead of Fast DDS's 3 s. A participant's first
announcements are sometimes missed by a peer that is busy starting (seen in about half of the runs
where the bootstrap and two composite processes start at once); until the next periodic
announcement that peer cannot see the participant's topics at all, so a 3 s period left a short
run's status and recording without a whole composite.
"""

from __future__ import annotations

import os
from pathlib import Path

__all__ = ['configure_dds', 'PROFILE', 'LOCALHOST_PROFILE']

PROFILE = Path(__file__).with_name('fastdds.xml')
LOCALHOST_PROFILE = Path(__file__).with_name('fastdds_localhost.xml')


def configure_dds() -> None:
    """Select our Fast DDS profile in this process's environment (inherited by its children)."""
    if os.environ.get('FASTRTPS_DEFAULT_PROFILES_FILE'):
        return
    if os.environ.get('ROS_AUTOMATIC_DISCOVERY_RANGE', '').upper() == 'LOCALHOST':
        os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'SYSTEM_DEFAULT'
        os.environ['FASTRTPS_DEFAULT_PROFILES_FILE'] = str(LOCALHOST_PROFILE)
    else:
        os.environ['FASTRTPS_DEFAULT_PROFILES_FILE'] = str(PROFILE)
