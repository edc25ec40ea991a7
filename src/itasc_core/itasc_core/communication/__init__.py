"""Communication (paper §7): events, data-flow ports with metadata, QoS and DDS settings."""

from .events import Event, EventListener, EventRaiser, events_topic
from .ports import InputPort, LocalBus, OutputPort, PortSpec, SemanticMismatch, check_connection
from .qos import DATA_QOS, DATA_READER_QOS, EVENT_LISTENER_QOS, EVENT_QOS, STATE_QOS

__all__ = ['Event', 'EventListener', 'EventRaiser', 'events_topic', 'InputPort', 'OutputPort', 'LocalBus',
           'PortSpec', 'SemanticMismatch', 'check_connection', 'DATA_QOS', 'DATA_READER_QOS', 'EVENT_QOS',
           'EVENT_LISTENER_QOS', 'STATE_QOS']
