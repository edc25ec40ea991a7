"""The Setpoint Generator ``hold``: hold the output where it was when the Task became active."""

from __future__ import annotations

from typing import Any

from ..setpoint_generator import HoldSetpoint
from .kind import SetpointKind

__all__ = ['Hold']


class Hold(SetpointKind):
    """Hold the output where the Task found it (each time it is activated)."""
    example = '{kind: hold}'

    @classmethod
    def generator(cls, params: Any) -> HoldSetpoint:
        return HoldSetpoint()
