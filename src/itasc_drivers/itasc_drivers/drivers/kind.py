"""What a Driver kind is (:mod:`itasc_drivers.drivers`) and their registry."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

from itasc_core.computation.parameters import NoParameters, ParameterModel
from itasc_core.kinds import Registry

__all__ = ['Driver', 'DRIVERS', 'DrivenRobot']


@dataclass(frozen=True)
class DrivenRobot:
    """What the model says of the robot a Driver drives: its kinematic model, its joints in order and
    their limits (the URDF's, overridden by the model's), and the application's rate."""

    name: str
    urdf: str
    base: str
    joints: list[str]
    limits: Mapping[str, list[float]]
    rate: float


class Driver:
    """A kind of Driver: the fields of its section, its entity and that entity's parameters."""

    #: The section's own fields (those after ``robot`` and ``kind``).
    Parameters: ClassVar[type[ParameterModel]] = NoParameters
    #: Its Functional Entity, as a composition model names a kind: ``package.module:Class``.
    entity: ClassVar[str]

    @classmethod
    def parameters(cls, section: Any, robot: DrivenRobot) -> dict[str, Any]:
        """The entity's parameters for the Driver ``section`` of ``robot``."""
        raise NotImplementedError

    @classmethod
    def problem(cls, section: Any, *, robot: DrivenRobot) -> tuple[tuple[str | int, ...], str] | None:
        """What in ``section`` does not fit ``robot`` (its joints, their limits): the path in the
        section and why, or None."""
        return None

    @classmethod
    def stand_in(cls, section: Any, *, robot: DrivenRobot, initial: Mapping[str, float]) -> list[str] | None:
        """The command line of a process that stands in for the outside driver ``section`` talks to,
        speaking what that driver speaks, with ``robot``'s joints at ``initial`` (by name), so that the
        application runs where that driver is not (a benchmark, a test); None when the Driver needs
        no other process (it simulates the robot itself)."""
        return None


DRIVERS: Registry[Driver] = Registry('itasc.drivers', what='driver', base=Driver)
