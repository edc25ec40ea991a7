"""DDS settings the pattern relies on (paper §7.2: no event may be lost; §6: a dead process must
lead the others to Safety, not take them down with it).

Call :func:`configure_dds` before ``rclpy.init`` (a composite process also
:func:`send_from_a_dds_thread`). Unless the user chose a Fast DDS profile of their own
(``FASTRTPS_DEFAULT_PROFILES_FILE``), it points Fast DDS at ours:

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

Every profile asks for 4 MiB socket receive buffers, which the kernel doubles (its default is
208 KiB, about 20 ms of a 10,000 events/s storm), so that a process busy for a moment does not have
the kernel drop datagrams. ``fastdds.xml`` sets it with ``sockets_size`` on the builtin transports
(which sizes the send buffers too; the participant's ``listenSocketBufferSize`` is not applied to
them), the others with the transport's ``receiveBufferSize``. Linux caps the size at
``net.core.rmem_max``; raise it where it is lower (README).

A process that stays behind longer still loses datagrams (a storm of 10,000 events/s for 10 s on a
loaded 2-core machine: 50,000-240,000 dropped at the bootstrap). One reason is rmw_fastrtps
(Jazzy): with a callback-based executor (rclpy's EventsExecutor) every sample that arrives makes it
count the reader's unread samples (``get_unread_count(true)``), a walk over every sample not yet
taken, so the DDS receive thread slows down as the backlog grows. A reliable reader asks for a lost
datagram again when the writer's heartbeat tells it what was sent, at most 256 sequence numbers per
answer; Fast DDS's default heartbeat period of 3 s repairs less than 100 events a second, by when a
fast writer has long dropped them from its history. So every profile gives every writer a
heartbeat every 0.1 s (a default ``data_writer`` profile; heartbeats are only sent while a reader
has not acknowledged everything), and the event queues hold a whole storm
(:data:`.qos.EVENT_DEPTH`): nothing is lost, the readers catch up after the storm.

Both announce their participant every 0.5 s instead of Fast DDS's 3 s. A participant's first
announcements are sometimes missed by a peer that is busy starting (seen in about half of the runs
where the bootstrap and two composite processes start at once); until the next periodic
announcement that peer cannot see the participant's topics at all, so a 3 s period left a short
run's status and recording without a whole composite.

Several machines (README "Several machines"): with ``ITASC_DDS_PEERS`` set to the IPv4 addresses
of every machine of the application (comma-separated, the same list on each), a profile generated
from :data:`PEERS_TEMPLATE` replaces both: UDPv4 only, no multicast, the SPDP announcements sent
by unicast to the first :data:`PEERS_RANGE` participant ports of every peer address (each process
of ours is a participant). ``ITASC_DDS_INTERFACES`` (optional) limits the addresses of this
machine that DDS uses (Fast DDS's interface whitelist; loopback is then left out, so a peer never
receives a 127.0.0.1 locator that would point back at itself). All machines need the same
``ROS_DOMAIN_ID``.
"""

from __future__ import annotations

import hashlib
import ipaddress
import os
import re
import tempfile
from pathlib import Path

__all__ = ['configure_dds', 'send_from_a_dds_thread', 'domain_id', 'peers_profile', 'profile_file', 'DdsSettingsError',
           'PROFILE', 'LOCALHOST_PROFILE', 'PEERS_TEMPLATE', 'PEERS_RANGE', 'MAX_DOMAIN_ID']

PROFILE = Path(__file__).with_name('fastdds.xml')
LOCALHOST_PROFILE = Path(__file__).with_name('fastdds_localhost.xml')
PEERS_TEMPLATE = Path(__file__).with_name('fastdds_peers.xml.in')
#: Participant ports per peer address that announcements go to (Fast DDS's default is 4).
PEERS_RANGE = 32
#: The largest ROS domain id whose UDP ports exist (7400 + 250 x domain + the participant's).
MAX_DOMAIN_ID = 232


class DdsSettingsError(ValueError):
    """An ``ITASC_DDS_*`` variable that is not a list of IPv4 addresses, or a ``ROS_DOMAIN_ID``
    that is not a domain id."""


def domain_id() -> int:
    """This process's ROS domain id (``ROS_DOMAIN_ID``, 0 when unset or empty, as rcl reads it);
    :class:`DdsSettingsError` for anything but an integer 0..:data:`MAX_DOMAIN_ID` (rcl would
    fail later, in ``rclpy.init``, with a traceback)."""
    text = os.environ.get('ROS_DOMAIN_ID', '').strip()
    if not text:
        return 0
    if not re.fullmatch(r'[0-9]+', text) or int(text) > MAX_DOMAIN_ID:
        raise DdsSettingsError(f'ROS_DOMAIN_ID={text!r} is not a ROS domain id: an integer 0..{MAX_DOMAIN_ID} '
                               '(0..101 keeps clear of Linux\'s ephemeral ports)')
    return int(text)


def _addresses(variable: str) -> list[str]:
    text = os.environ.get(variable, '')
    addresses = [item for item in re.split(r'[\s,;]+', text) if item]
    for address in addresses:
        try:
            ipaddress.IPv4Address(address)
        except ValueError:
            raise DdsSettingsError(f'{variable}={text!r}: {address!r} is not an IPv4 address') from None
    return addresses


def _locators(addresses: list[str]) -> str:
    return ''.join(f'<locator><udpv4><address>{a}</address></udpv4></locator>' for a in addresses)


def peers_profile(*, peers: list[str], interfaces: list[str]) -> Path:
    """The generated Fast DDS profile for ``peers`` (and the ``interfaces`` whitelist): a file
    named after its content in the temporary directory, written once."""
    whitelist = (f'<interfaceWhiteList>{"".join(f"<address>{a}</address>" for a in interfaces)}'
                 '</interfaceWhiteList>') if interfaces else ''
    text = PEERS_TEMPLATE.read_text().format(range=PEERS_RANGE, whitelist=whitelist, peers=_locators(peers))
    return profile_file(text, name='itasc_fastdds_peers')


def profile_file(text: str, *, name: str) -> Path:
    """A Fast DDS profile ``text`` as a file ``<name>_<digest>.xml`` in the temporary directory,
    named after its content and written once (atomically: processes starting together share it)."""
    digest = hashlib.sha256(text.encode()).hexdigest()[:16]
    path = Path(tempfile.gettempdir()) / f'{name}_{digest}.xml'
    if not path.exists():
        partial = path.with_suffix(f'.{os.getpid()}.tmp')
        partial.write_text(text)
        partial.replace(path)
    return path


def send_from_a_dds_thread() -> None:
    """In a composite process (``--deploy per-composite``, a composite on another host), have Fast
    DDS send every sample from a thread of its own (rmw_fastrtps's asynchronous publication mode),
    unless the user chose a mode (``RMW_FASTRTPS_PUBLICATION_MODE``). Call it before ``rclpy.init``;
    the composite processes this one starts inherit it.

    Such a process's tick is triggered over DDS and sends the most: ``approach_object`` at 500 Hz,
    the program's process sends six messages a tick, and ``Publisher.publish`` (the ``sendto`` on
    these VMs) was 44 % of its tick; its main thread took 58-63 % of a core, fell behind by up to
    the trigger reader's depth (20 ms) and lost 1-3 % of its triggers. Sending from the DDS thread,
    four alternating pairs of 20 s runs: the Solver stepped at 497.2-499.5 Hz against 486.1-495.0 Hz,
    the command the Driver applied was no older (median 1.0-1.9 ticks either way), the root's tick
    p99 unchanged. The bootstrap's process (the root's Timer) keeps sending from the ticking thread:
    with every process sending asynchronously the root's tick p99 doubled (4.0-4.3 ms against
    1.5-2.1 ms; its tick waits at times for the writer's lock that the descheduled sending thread
    holds). See ``docs/speed.md``, "The seventh session".
    """
    os.environ.setdefault('RMW_FASTRTPS_PUBLICATION_MODE', 'ASYNCHRONOUS')


def configure_dds() -> None:
    """Select our Fast DDS profile in this process's environment (inherited by its children).

    Raises :class:`DdsSettingsError` for an ``ITASC_DDS_PEERS``/``ITASC_DDS_INTERFACES`` that is
    not a list of IPv4 addresses, or a ``ROS_DOMAIN_ID`` that is not a domain id."""
    domain_id()
    if os.environ.get('FASTRTPS_DEFAULT_PROFILES_FILE'):
        return
    peers = _addresses('ITASC_DDS_PEERS')
    if peers:
        profile = peers_profile(peers=peers, interfaces=_addresses('ITASC_DDS_INTERFACES'))
        os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'SYSTEM_DEFAULT'
        os.environ['FASTRTPS_DEFAULT_PROFILES_FILE'] = str(profile)
        return
    if os.environ.get('ROS_AUTOMATIC_DISCOVERY_RANGE', '').upper() == 'LOCALHOST':
        os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'SYSTEM_DEFAULT'
        os.environ['FASTRTPS_DEFAULT_PROFILES_FILE'] = str(LOCALHOST_PROFILE)
    else:
        os.environ['FASTRTPS_DEFAULT_PROFILES_FILE'] = str(PROFILE)
