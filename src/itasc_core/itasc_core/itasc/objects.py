"""Object: a body without controllable DOF that carries object frames (paper §4.1 "Robots and
Objects").

Its world pose is fixed, set per cycle from a Sensor (``set_pose``), or given by a trajectory
function of time evaluated in ``update(t)``. Object frames are offsets from the object's origin;
the origin itself is the frame ``'origin'``.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
import pinocchio as pin

from .robot import se3

__all__ = ['Object', 'periodic_translation']


def periodic_translation(*, xyz: Sequence[float], rpy: Sequence[float], amplitude: Sequence[float],
                         period: float) -> Callable[[float], pin.SE3]:
    """A trajectory oscillating about ``xyz`` by ``amplitude * sin(2 pi t / period)`` per axis."""
    centre, swing = np.asarray(xyz, dtype=float), np.asarray(amplitude, dtype=float)
    rotation = se3((0.0, 0.0, 0.0), rpy).rotation

    def pose(t: float) -> pin.SE3:
        return pin.SE3(rotation, centre + swing * np.sin(2.0 * np.pi * t / period))
    return pose


class Object:
    """A fixed or moving object with named object frames."""

    def __init__(self, name: str, *, xyz: Sequence[float] = (0.0, 0.0, 0.0),
                 rpy: Sequence[float] = (0.0, 0.0, 0.0),
                 trajectory: Callable[[float], pin.SE3] | None = None) -> None:
        """An object at ``xyz``/``rpy`` in the world, or moving along ``trajectory(t)``."""
        self.name = name
        self.trajectory = trajectory
        self._pose = se3(xyz, rpy)
        self._offsets: dict[str, pin.SE3] = {'origin': pin.SE3.Identity()}
        self._poses: dict[str, pin.SE3] = {'origin': self._pose}

    @property
    def frame_names(self) -> list[str]:
        return list(self._offsets)

    def add_frame(self, name: str, *, xyz: Sequence[float] = (0.0, 0.0, 0.0),
                  rpy: Sequence[float] = (0.0, 0.0, 0.0)) -> None:
        """Add an object frame at an offset from the object's origin."""
        if name in self._offsets:
            raise ValueError(f'Object {self.name!r} already has a frame {name!r}')
        self._offsets[name] = se3(xyz, rpy)
        self._poses[name] = self._pose * self._offsets[name]

    def set_pose(self, pose: pin.SE3) -> None:
        """Set the world pose of the object's origin (e.g. from a pose Sensor)."""
        self._pose = pin.SE3(pose)
        self._poses = {n: self._pose * off for n, off in self._offsets.items()}

    def update(self, t: float | None = None) -> None:
        """Evaluate the trajectory at time ``t`` (no-op for a fixed or sensor-driven object)."""
        if self.trajectory is not None and t is not None:
            self.set_pose(self.trajectory(t))

    def has_frame(self, name: str) -> bool:
        return name in self._offsets

    def frame_pose(self, name: str = 'origin') -> pin.SE3:
        """World pose of an object frame (shared, do not modify; valid until the pose changes)."""
        try:
            return self._poses[name]
        except KeyError:
            raise KeyError(f'Object {self.name!r} has no frame {name!r}; '
                           f'frames: {self.frame_names}') from None
