"""The task type ``joint``: joint positions (paper §4.1 "VKC", a joint-space chain)."""

from __future__ import annotations

from itasc_core.computation.parameters import Names, ParameterModel
from pydantic import Field

from ..vkc import JointVKC
from .kind import TaskType

__all__ = ['Joint']


class Joints(ParameterModel):
    joints: Names = Field(min_length=1, frozen=True)
    """The joints, by name, each once."""


class Joint(TaskType):
    """The positions of ``joints``: one feature per joint."""

    Parameters = Joints
    reads = 'joints'

    @classmethod
    def chain(cls, params: Joints) -> JointVKC:
        return JointVKC(params.joints)
