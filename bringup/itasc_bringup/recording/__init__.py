"""Recording a run to MCAP as a ROS 2 bag (SPEC: "recording the whole run to MCAP")."""

from .recorder import Recorder, install_signal_handlers

__all__ = ['Recorder', 'install_signal_handlers']
