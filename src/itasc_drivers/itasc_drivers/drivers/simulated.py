"""The Driver ``simulated``: a robot that integrates the commanded joint velocities
(:class:`itasc_drivers.simulated_robot.SimulatedRobot`), from ``initial`` joint positions."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from itasc_core.computation.parameters import ParameterModel
from pydantic import Field

from .kind import DrivenRobot, Driver

__all__ = ['Simulated']


class SimulatedSection(ParameterModel):
    initial: dict[str, float] = Field(default_factory=dict)
    """Initial joint positions by joint name [rad or m] (omitted: 0)."""


class Simulated(Driver):
    """A simulated robot: integrates the commanded velocities within the joint limits."""

    Parameters = SimulatedSection
    entity = 'itasc_drivers.simulated_robot:SimulatedRobot'

    @classmethod
    def parameters(cls, section: SimulatedSection, robot: DrivenRobot) -> dict[str, Any]:
        return {'robot': robot.name, 'urdf': robot.urdf, 'base': robot.base, 'initial': dict(section.initial),
                **robot.limits}

    @classmethod
    def problem(cls, section: SimulatedSection, *, robot: str,
                joints: Sequence[str]) -> tuple[tuple[str | int, ...], str] | None:
        for joint in section.initial:
            if joint not in joints:
                return ('initial', joint), f"robot '{robot}' has no joint '{joint}'; joints: {list(joints)}"
        return None
