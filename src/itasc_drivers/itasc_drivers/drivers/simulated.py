"""The Driver ``simulated``: a robot that integrates the commanded joint velocities
(:class:`itasc_drivers.simulated_robot.SimulatedRobot`), from ``initial`` joint positions."""

from __future__ import annotations

from typing import Any

from itasc_core.computation.parameters import ParameterModel
from pydantic import Field

from .kind import DrivenRobot, Driver

__all__ = ['Simulated']


class SimulatedSection(ParameterModel):
    initial: dict[str, float] = Field(default_factory=dict)
    """Initial joint positions by joint name [rad or m], each within the joint's limits (omitted: 0)."""


class Simulated(Driver):
    """A simulated robot: integrates the commanded velocities within the joint limits."""

    Parameters = SimulatedSection
    entity = 'itasc_drivers.simulated_robot:SimulatedRobot'

    @classmethod
    def parameters(cls, section: SimulatedSection, robot: DrivenRobot) -> dict[str, Any]:
        return {'robot': robot.name, 'urdf': robot.urdf, 'base': robot.base, 'initial': dict(section.initial),
                **robot.limits}

    @classmethod
    def problem(cls, section: SimulatedSection, *, robot: DrivenRobot) -> tuple[tuple[str | int, ...], str] | None:
        joints = robot.joints
        for joint, value in section.initial.items():
            if joint not in joints:
                return ('initial', joint), f"robot '{robot.name}' has no joint '{joint}'; joints: {joints}"
            i = joints.index(joint)
            lower, upper = robot.limits['lower'][i], robot.limits['upper'][i]
            if not lower <= value <= upper:  # the simulated robot would start clamped, elsewhere than asked
                return ('initial', joint), (f"{value:g} is outside the limits of '{joint}', [{lower:g}, {upper:g}] "
                                            '(rad, or m for a prismatic joint)')
        return None
