"""Recording a run as a rosbag2 bag, or one MCAP file (SPEC: "recording the whole run to MCAP";
paper §6.1/§7): :class:`Recorder` (the node), :mod:`.bag` (storage), :mod:`.definitions` (message
definitions and type hashes), :mod:`.topics` (the data-flow topics of a model)."""

from .recorder import Recorder, install_signal_handlers

__all__ = ['Recorder', 'install_signal_handlers']
