"""Feature coordinates of a pose (paper §4.1 "VKC", the Scene's relations): the pose ``T_{o1,o2}``
of o2 in o1 as ``xyz_log3``, ``[p, log3(R)]`` (names x y z rx ry rz, a rotation triple at row 3), or
as ``log6``, ``log6(T)``. The Scene entity's relations, the Cartesian VKC, the Setpoint Generator and
the visualization go between a pose and its coordinates with these functions only.
"""

from __future__ import annotations

from typing import Literal, TypeAlias

import numpy as np
import pinocchio as pin

__all__ = ['Coordinates', 'POSE_FEATURES', 'pose_coordinates', 'pose_features', 'features_pose']

#: The feature coordinates of a pose.
Coordinates: TypeAlias = Literal['xyz_log3', 'log6']
#: Their names.
POSE_FEATURES = ('x', 'y', 'z', 'rx', 'ry', 'rz')


def pose_coordinates(rotation: int | None) -> Coordinates:
    """The coordinates of a pose's features: ``xyz_log3`` where they mark a rotation triple."""
    return 'xyz_log3' if rotation is not None else 'log6'


def pose_features(pose: pin.SE3, *, coordinates: Coordinates) -> np.ndarray:
    """The feature coordinates of a pose of o2 in o1 (a relation, or a pose setpoint)."""
    if coordinates == 'log6':
        return pin.log6(pose).vector
    return np.concatenate([pose.translation, pin.log3(pose.rotation)])


def features_pose(features: np.ndarray, *, coordinates: Coordinates) -> pin.SE3:
    """The pose of o2 in o1 whose feature coordinates are ``features`` (inverse of :func:`pose_features`)."""
    if coordinates == 'log6':
        return pin.exp6(pin.Motion(features[:6]))
    return pin.SE3(pin.exp3(features[3:6]), features[0:3].copy())
