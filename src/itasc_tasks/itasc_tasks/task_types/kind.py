"""What a task type is (:mod:`itasc_tasks.task_types`) and their registry."""

from __future__ import annotations

from typing import Any, ClassVar, Literal, TypeAlias

from itasc_core.computation.parameters import ParameterModel
from itasc_core.kinds import Registry
from pydantic import Field

from ..vkc import JointChain, VirtualKinematicChain

__all__ = ['TaskType', 'TASK_TYPES', 'FramePair', 'Chain']

#: The math chain of a task type (:mod:`itasc_tasks.vkc`): ``(chi_f, J_f)`` of a relation between o1
#: and o2 (``reads = 'relation'``) or of the joint positions (``reads = 'joints'``).
Chain: TypeAlias = VirtualKinematicChain | JointChain


class FramePair(ParameterModel):
    """A chain between two object frames."""

    o1: str = Field(min_length=1, frozen=True)
    """First object frame: ``<robot>/<frame>``, ``<object>/<frame>``, ``<object>`` or ``world``."""
    o2: str = Field(min_length=1, frozen=True)
    """Second object frame, as o1."""


class TaskType:
    """A kind of Task: the parameters of its chain (its fields in a Task of the application model
    and the VKC entity's ROS parameters), its feature coordinates and its math chain."""

    #: The chain's parameters.
    Parameters: ClassVar[type[ParameterModel]] = FramePair
    #: What the chain reads: the Scene's ``relation`` between ``o1`` and ``o2`` (a
    #: :class:`FramePair`), or the program's ``joints`` positions.
    reads: ClassVar[Literal['relation', 'joints']] = 'relation'
    #: Whether its features are never negative (bounds below zero are refused).
    nonnegative: ClassVar[bool] = False
    #: Whether a setpoint may be given as the pose of o2 in o1.
    pose_setpoints: ClassVar[bool] = False

    @classmethod
    def features(cls, params: Any) -> tuple[str, ...]:
        """The names of the chain's feature coordinates."""
        return cls.chain(params).names

    @classmethod
    def chain(cls, params: Any) -> Chain:
        """The math chain for ``params``."""
        raise NotImplementedError


TASK_TYPES: Registry[TaskType] = Registry('itasc.task_types', what='task type', base=TaskType)
