"""QoS profiles for the three communication mechanisms of the pattern (paper §7).

Events must never be lost (paper §7.2: "a buffer must be used to avoid the loss of events"), so
they travel reliably with the whole history kept until delivered. Data flow is reliable with a
short queue: a controller wants the newest sample, a recorder wants every one it can get.
"""

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

__all__ = ['EVENT_QOS', 'DATA_QOS', 'STATE_QOS']

EVENT_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_ALL,
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
