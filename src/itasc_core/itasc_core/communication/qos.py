"""QoS profiles for the three communication mechanisms of the pattern (paper §7).

Events must never be lost (paper §7.2: "a buffer must be used to avoid the loss of events"), so
they travel reliably with a deep history. Data flow is reliable with a
short queue: a controller wants the newest sample, a recorder wants every one it can get.
"""

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

__all__ = ['EVENT_QOS', 'DATA_QOS', 'STATE_QOS']

#: KEEP_LAST with a deep queue rather than KEEP_ALL: Fast DDS bounds KEEP_ALL by its default
#: resource limits (5000 samples per reader), beyond which same-process delivery drops samples
#: silently; 10000 outstanding events per reader is more than a composite ever accumulates
#: between two spins.
EVENT_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=10000,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)

DATA_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=10,
    reliability=ReliabilityPolicy.RELIABLE,
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
