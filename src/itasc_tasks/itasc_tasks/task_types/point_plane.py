"""The task type ``point_plane``: the signed distance of o2's origin to the plane through o1's origin
with unit ``normal`` (in o1 coordinates), e.g. a hand kept above a table (an inequality with
``d_min``) or brought onto a surface (paper §4.1 "VKC": a 1-D chain)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
from pydantic import field_validator

from ..vkc import Features
from .kind import FramePair, TaskType

__all__ = ['PointPlane', 'PointPlaneVKC']


class PlaneChain(FramePair):
    normal: tuple[float, float, float] = (0.0, 0.0, 1.0)
    """The plane's normal in o1 coordinates (normalised; the side it points to is positive)."""

    @field_validator('normal')
    @classmethod
    def _not_zero(cls, value: tuple[float, float, float]) -> tuple[float, float, float]:
        if not np.linalg.norm(value) > 1e-9:
            raise ValueError('the normal must not be zero')
        return value


class PointPlaneVKC:
    """chi_f = n . p, p = o2's origin in o1, n the unit normal in o1; J_f = n^T J_p."""

    names = ('distance',)
    rotation = None

    def __init__(self, *, normal: tuple[float, float, float]) -> None:
        self.normal = np.asarray(normal, dtype=float) / np.linalg.norm(normal)

    def __call__(self, pose: pin.SE3, jacobian: np.ndarray, /) -> Features:
        return np.array([self.normal @ pose.translation]), (self.normal @ jacobian[:3])[None, :]


class PointPlane(TaskType):
    """The signed distance of o2's origin to the plane through o1 normal to ``normal``: ``distance``."""

    Parameters = PlaneChain
    example = ('{name: AboveTable, type: point_plane, o1: table, o2: panda/panda_hand, normal: [0, 0, 1],\n'
               ' constraint: inequality, d_min: 0.05}')

    @classmethod
    def chain(cls, params: PlaneChain) -> PointPlaneVKC:
        return PointPlaneVKC(normal=params.normal)
