"""Virtual Kinematic Chains (paper §4.1 "VKC"): the task space between two object frames o1, o2,
its feature coordinates chi_f and their Jacobian on the program-wide joint velocities.

After ``compute(scene)``: ``features`` (chi_f), ``jacobian`` (d chi_f / dt = jacobian @ qdot,
except for rotation rows, see ``CartesianVKC``) and ``names`` (one per feature coordinate).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pinocchio as pin
from itasc_core.itasc.scene import Scene

from .constraint_output import compact_index

__all__ = ['CartesianVKC', 'DistanceVKC', 'JointVKC']


class CartesianVKC:
    """Full 6-D chain from o1 to o2: the pose ``T_{o1,o2}`` of o2 expressed in o1.

    ``coordinates='xyz_log3'`` (default): chi_f = [p, log3(R)] (names x y z rx ry rz); Jacobian
    rows = ``[d/dt p ; omega]``, omega the angular velocity of o2 relative to o1 in o1
    coordinates (``Scene.relative_jacobian``). The rotation rows are *not* d/dt log3(R): the
    controller's rotation error must be ``log3(R_d R^T)`` (in o1), which is what
    ``constraint_controller`` computes for a complete rx, ry, rz triple.

    ``coordinates='log6'``: chi_f = log6(T_{o1,o2}) (pink's frame-task error, body twist
    coordinates of o2) with the exact Jacobian ``Jlog6(T) J_body``; plain vector arithmetic then
    applies to errors (straight lines in exponential coordinates).
    """

    names = ('x', 'y', 'z', 'rx', 'ry', 'rz')

    def __init__(self, o1: str, o2: str, *, coordinates: str = 'xyz_log3') -> None:
        if coordinates not in ('xyz_log3', 'log6'):
            raise ValueError(f"coordinates must be 'xyz_log3' or 'log6', got {coordinates!r}")
        self.o1, self.o2, self.coordinates = o1, o2, coordinates
        self.rotation_names = ('rx', 'ry', 'rz') if coordinates == 'xyz_log3' else ()
        self.pose = pin.SE3.Identity()
        self.features = np.zeros(6)
        self.jacobian = np.zeros((6, 0))

    def features_of(self, pose: pin.SE3) -> np.ndarray:
        """Feature coordinates of a relative pose (to turn an SE3 setpoint into chi_f,d)."""
        if self.coordinates == 'log6':
            return pin.log6(pose).vector
        return np.concatenate([pose.translation, pin.log3(pose.rotation)])

    def compute(self, scene: Scene) -> None:
        self.pose = scene.relative_pose(self.o1, self.o2)
        self.features = self.features_of(self.pose)
        J = scene.relative_jacobian(self.o1, self.o2)
        if self.coordinates == 'log6':  # body twist of o2 relative to o1, then d log6
            J = pin.Jlog6(self.pose) @ np.matmul(self.pose.rotation.T,
                                                 J.reshape(2, 3, -1)).reshape(6, -1)
        self.jacobian = J


class DistanceVKC:
    """1-D chain: distance from o1 to o2's origin.

    Point-point (``normal=None``): ``chi_f = ||p||``, p = o2's origin in o1. Point-plane: the
    signed distance ``n . p`` of o2's origin to the plane through o1's origin with unit
    ``normal`` given in o1 coordinates.
    """

    names = ('distance',)
    rotation_names = ()

    def __init__(self, o1: str, o2: str, *, normal: Sequence[float] | None = None) -> None:
        self.o1, self.o2 = o1, o2
        self.normal = None if normal is None else np.asarray(normal, float) / np.linalg.norm(normal)
        self.features = np.zeros(1)
        self.jacobian = np.zeros((1, 0))

    def compute(self, scene: Scene) -> None:
        p = scene.relative_pose(self.o1, self.o2).translation
        Jp = scene.relative_jacobian(self.o1, self.o2)[:3]
        if self.normal is not None:
            direction = self.normal
            self.features[0] = direction @ p
        else:
            distance = float(np.linalg.norm(p))
            direction = p / distance if distance > 1e-12 else np.zeros(3)
            self.features[0] = distance
        self.jacobian = (direction @ Jp)[None, :]


class JointVKC:
    """Joint-space chain: chi_f = positions of the selected joints (all joints if ``joints`` is
    None), Jacobian = selection rows of the identity."""

    rotation_names = ()

    def __init__(self, joints: Sequence[str] | None = None) -> None:
        self.joints = None if joints is None else list(joints)
        self.names: tuple[str, ...] = tuple(self.joints or ())
        self.features = np.zeros(len(self.names))
        self.jacobian = np.zeros((len(self.names), 0))
        self._version = -1
        self._index: slice | np.ndarray = slice(0)

    def compute(self, scene: Scene) -> None:
        if self._version != scene.version:  # (re)bind to the program-wide joint vector
            self.names = tuple(scene.joint_names if self.joints is None else self.joints)
            self._index = compact_index(list(scene.joint_indices(self.names)))
            self.jacobian = np.eye(scene.nv)[self._index]
            self._version = scene.version
        self.features = scene.q[self._index].copy()
