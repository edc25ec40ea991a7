"""The task type ``distance``: the distance between the origins of o1 and o2 (paper §4.1 "VKC")."""

from __future__ import annotations

from ..vkc import DistanceVKC
from .kind import FramePair, TaskType

__all__ = ['Distance']


class Distance(TaskType):
    """The distance between the origins of o1 and o2: ``distance``."""

    nonnegative = True

    @classmethod
    def chain(cls, params: FramePair) -> DistanceVKC:
        return DistanceVKC()
