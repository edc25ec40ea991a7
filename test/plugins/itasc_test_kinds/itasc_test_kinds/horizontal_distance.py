"""The task type ``horizontal_distance``: the distance between the origins of o1 and o2 in o1's xy
plane, ``sqrt(px^2 + py^2)``, p = o2's origin in o1 (height ignored)."""

from __future__ import annotations

import numpy as np
from itasc_tasks.task_types import FramePair, TaskType

__all__ = ['HorizontalDistance']


class HorizontalDistanceVKC:
    """chi_f = ||(px, py)||; J_f = (px J_x + py J_y) / ||(px, py)||."""

    names = ('horizontal',)
    rotation = None

    def __call__(self, pose, jacobian: np.ndarray, /) -> tuple[np.ndarray, np.ndarray]:
        p, J = pose.translation[:2], jacobian[:2]
        d = float(np.linalg.norm(p))
        return np.array([d]), ((p / d) @ J if d > 1e-12 else np.zeros(J.shape[1]))[None, :]


class HorizontalDistance(TaskType):
    """The distance between o1 and o2 in o1's xy plane: ``horizontal``."""

    nonnegative = True

    @classmethod
    def chain(cls, params: FramePair) -> HorizontalDistanceVKC:
        return HorizontalDistanceVKC()
