"""QoS profiles for the three communication mechanisms of the pattern (paper §7).

Events must never be lost (paper §7.2: "a buffer must be used to avoid the loss of events"), so
they travel reliably with a deep history. Data flow is offered reliably with a short queue (a
recorder wants every sample it can get) and read best effort between composites: a controller
wants the newest sample. What comes from another program (a driver's joint states, a pose, a
setpoint topic) is read best effort, so that any publisher matches.

:func:`qos_profiles` writes offered profiles down as a rosbag2 bag keeps them (its metadata and
MCAP channels), for a recording written from several processes (:mod:`.sample_stream`).
"""

from collections.abc import Iterable
from typing import Any

from rclpy.qos import DurabilityPolicy, HistoryPolicy, LivelinessPolicy, QoSProfile, ReliabilityPolicy

__all__ = ['EVENT_DEPTH', 'EVENT_QOS', 'EVENT_LISTENER_QOS', 'DATA_QOS', 'DATA_READER_QOS', 'OUTSIDE_QOS',
           'STATE_QOS', 'qos_profiles']

#: How many events a writer keeps and a reader holds untaken: a whole storm of issue #8 (10,000
#: events/s for 10 s). The queues are the buffer of paper §7.2: a reader whose process falls
#: behind (a busy or starved CPU) holds the backlog instead of dropping its oldest events, and a
#: writer still has every event a reader has not acknowledged (a datagram the kernel dropped) to
#: send again. KEEP_LAST rather than KEEP_ALL: a full KEEP_ALL writer blocks the publishing thread
#: (the control loop raises events too); Fast DDS allocates the queues as they fill, so memory
#: grows with the backlog, bounded by this depth.
EVENT_DEPTH = 100_000

#: What an event writer offers. Transient local: a writer keeps its last EVENT_DEPTH events for a
#: reader that matches it late. Discovery between processes is not synchronised with the first
#: events: a composite process's Coordinator may raise its first events before the recorder in
#: another process has matched its writer (seen under load: a recording without a Coordinator's
#: first three events); the recorder asks for the history and gets them.
EVENT_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=EVENT_DEPTH,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)

#: What an event listener (an entity, through its process's event hub) asks for: volatile, so that
#: an entity acts only on the events raised after it listens (never on a writer's history, e.g. the
#: deploy command that created it), and so that it also hears volatile writers from outside (a
#: hand-written node, ``ros2 topic pub``), which a transient-local reader does not match.
EVENT_LISTENER_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=EVENT_DEPTH,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)

#: What a data-flow output offers: reliable, so that every reader matches it (a user's node with
#: rclpy's default QoS, RViz) and one that asks for it (a recorder) has a lost datagram sent again.
DATA_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=10,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)
#: What a data-flow input asks of an output in another process, and a child composite's Scheduler
#: of its trigger: best effort. A tick wants the newest sample, and a reliable reader would hold
#: back every sample after a lost datagram until the writer's next heartbeat has it sent again (up
#: to 0.1 s, :mod:`.dds`), then hand over the old one first. It also saves the writer the
#: acknowledgements it tracks for a reliable reader (``--deploy per-composite`` at 500 Hz, CPU a
#: tick over the processes but the display: 3665/3573/3631 -> 3406/3446/3563 us, 2-core VM).
DATA_READER_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=10,
    reliability=ReliabilityPolicy.BEST_EFFORT,
    durability=DurabilityPolicy.VOLATILE,
)
#: What a subscription to another program's topic asks for (a driver's joint states, a localisation's
#: poses, a user's setpoint topic): best effort and volatile, which every publisher matches, reliable
#: (ros2_control's joint_state_broadcaster) or best effort (``qos_profile_sensor_data``, as many
#: drivers and simulators publish), transient local or not (REP 2003: subscribe to sensor data with
#: the sensor data QoS). A reliable reader does not match a best-effort writer: the data never came,
#: and the silent-driver Monitor went to Safety. The newest value is what is used.
OUTSIDE_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=10,
    reliability=ReliabilityPolicy.BEST_EFFORT,
    durability=DurabilityPolicy.VOLATILE,
)

#: Coordinator states are latched so that a late joiner (a status display, a recorder) sees the
#: current state of every composite.
STATE_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=100,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)


def _duration(duration: Any) -> dict[str, int]:
    ns = int(duration.nanoseconds)
    return {'sec': ns // 1_000_000_000, 'nsec': ns % 1_000_000_000}


def qos_profiles(profiles: Iterable[QoSProfile]) -> list[dict[str, Any]]:
    """Offered QoS profiles as rosbag2 (metadata version 9) writes them."""
    return [{
        'history': HistoryPolicy(p.history).name.lower(),
        'depth': int(p.depth),
        'reliability': ReliabilityPolicy(p.reliability).name.lower(),
        'durability': DurabilityPolicy(p.durability).name.lower(),
        'deadline': _duration(p.deadline),
        'lifespan': _duration(p.lifespan),
        'liveliness': LivelinessPolicy(p.liveliness).name.lower(),
        'liveliness_lease_duration': _duration(p.liveliness_lease_duration),
        'avoid_ros_namespace_conventions': bool(p.avoid_ros_namespace_conventions),
    } for p in profiles]
