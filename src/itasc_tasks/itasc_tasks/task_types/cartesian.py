"""The task type ``cartesian``: the full pose of o2 in o1 (paper §4.1 "VKC")."""

from __future__ import annotations

from typing import Literal

from ..vkc import CartesianVKC
from .kind import FramePair, TaskType

__all__ = ['Cartesian']


class CartesianChain(FramePair):
    coordinates: Literal['xyz_log3', 'log6'] = 'xyz_log3'
    """Orientation coordinates: ``xyz_log3`` (translation and rotation log) or ``log6`` (SE(3) log)."""


class Cartesian(TaskType):
    """The pose of o2 in o1: x, y, z, rx, ry, rz."""

    Parameters = CartesianChain
    pose_setpoints = True

    @classmethod
    def chain(cls, params: CartesianChain) -> CartesianVKC:
        return CartesianVKC(coordinates=params.coordinates)
