"""The host agent's protocol (paper §4.4, several machines): its topics, their QoS and its
timings, shared by the agent (:mod:`.host_agent`) and the parents it serves (:mod:`.remote`)."""

from __future__ import annotations

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

__all__ = ['requests_topic', 'status_topic', 'AGENT_QOS', 'PERIOD', 'HOLD_TIMEOUT', 'LOST_AFTER', 'HOST_NAME']

#: How often the agent reports and the parents hold their composites [s].
PERIOD = 0.2
#: A composite not held for this long has lost its parent [s].
HOLD_TIMEOUT = 3.0
#: An agent not heard for this long is lost, and its composites with it [s].
LOST_AFTER = 2.0
#: Host names are model names (``host:`` of a composite).
HOST_NAME = r'^[A-Za-z][A-Za-z0-9_]*$'

AGENT_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=100, reliability=ReliabilityPolicy.RELIABLE,
                       durability=DurabilityPolicy.VOLATILE)


def requests_topic(host: str) -> str:
    return f'/itasc_hosts/{host}/requests'


def status_topic(host: str) -> str:
    return f'/itasc_hosts/{host}/status'
