"""Virtual Kinematic Chains (paper §4.1 "VKC"): the feature coordinates chi_f of a Task's chain and
their Jacobian J_f on the program-wide joint velocities (d chi_f / dt = J_f qdot, except for rotation
rows, see :class:`CartesianVKC`), as functions of what the chain reads.

A chain between two object frames o1, o2 (:class:`VirtualKinematicChain`) reads their relation: the
pose ``T_{o1,o2}`` of o2 in o1 and its Jacobian, the twist ``[d/dt p ; omega]`` of o2 relative to o1
expressed in o1 (``Scene.relative_jacobian``, the Scene entity's ``relation_<task>``). A joint chain
(:class:`JointChain`) reads the program's joint names and positions. The VKC entity and
:class:`~itasc_tasks.task.TaskComputation` call the same chains.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Protocol, TypeAlias

import numpy as np
import pinocchio as pin
from itasc_core.itasc.coordinates import POSE_FEATURES, Coordinates, pose_features

from .constraint_output import compact_index

__all__ = ['VirtualKinematicChain', 'JointChain', 'Features', 'CartesianVKC', 'DistanceVKC', 'JointVKC']

#: ``(chi_f, J_f)``: feature coordinates and their Jacobian on the program-wide joint velocities.
Features: TypeAlias = tuple[np.ndarray, np.ndarray]


class VirtualKinematicChain(Protocol):
    """A chain between o1 and o2: ``(chi_f, J_f)`` from the relation ``T_{o1,o2}`` and its Jacobian."""

    @property
    def names(self) -> tuple[str, ...]:
        """One per feature coordinate."""

    @property
    def rotation(self) -> int | None:
        """First row of a complete ``(rx, ry, rz)`` log3 triple in chi_f, or None."""

    def __call__(self, pose: pin.SE3, jacobian: np.ndarray, /) -> Features: ...


class JointChain(Protocol):
    """A chain on joints: ``(chi_f, J_f)`` from the program's joint names and positions."""

    @property
    def names(self) -> tuple[str, ...]: ...

    @property
    def rotation(self) -> None: ...

    def __call__(self, joint_names: Sequence[str], q: np.ndarray, /) -> Features: ...


class CartesianVKC:
    """Full 6-D chain from o1 to o2: the pose ``T_{o1,o2}`` of o2 expressed in o1, in the coordinates
    of :mod:`itasc_core.itasc.coordinates`.

    ``coordinates='xyz_log3'`` (default): chi_f = [p, log3(R)] (names x y z rx ry rz); J_f is the
    relation's Jacobian ``[d/dt p ; omega]``, omega the angular velocity of o2 relative to o1 in o1.
    The rotation rows are *not* d/dt log3(R): the controller's rotation error must be
    ``log3(R_d R^T)`` (in o1), which :func:`~itasc_tasks.constraint_controller.control_error`
    computes for a complete rx, ry, rz triple (``rotation``).

    ``coordinates='log6'``: chi_f = log6(T_{o1,o2}) (pink's frame-task error, body twist
    coordinates of o2) with the exact Jacobian ``Jlog6(T) J_body``; plain vector arithmetic then
    applies to errors (straight lines in exponential coordinates).
    """

    names = POSE_FEATURES

    def __init__(self, *, coordinates: Coordinates = 'xyz_log3') -> None:
        if coordinates not in ('xyz_log3', 'log6'):
            raise ValueError(f"coordinates must be 'xyz_log3' or 'log6', got {coordinates!r}")
        self.coordinates: Coordinates = coordinates
        self.rotation = 3 if coordinates == 'xyz_log3' else None

    def __call__(self, pose: pin.SE3, jacobian: np.ndarray, /) -> Features:
        features = pose_features(pose, coordinates=self.coordinates)
        if self.coordinates == 'log6':  # body twist of o2 relative to o1, then d log6
            jacobian = pin.Jlog6(pose) @ np.matmul(pose.rotation.T, jacobian.reshape(2, 3, -1)).reshape(6, -1)
        return features, jacobian


class DistanceVKC:
    """1-D chain: the distance between the origins of o1 and o2, ``chi_f = ||p||``, p = o2's origin
    in o1 (a point-plane distance is the task type ``point_plane``)."""

    names = ('distance',)
    rotation = None

    def __call__(self, pose: pin.SE3, jacobian: np.ndarray, /) -> Features:
        p = pose.translation
        distance = math.sqrt(p.dot(p))  # np.linalg.norm's own sum, without its Python checks
        direction = p / distance if distance > 1e-12 else np.zeros(3)
        return np.array([distance]), direction.dot(jacobian[:3])[None, :]


class JointVKC:
    """Joint-space chain: chi_f = positions of ``joints``, J_f = their rows of the identity on the
    program's joints (bound again when those change)."""

    rotation = None

    def __init__(self, joints: Sequence[str]) -> None:
        self.names = tuple(joints)
        self._joint_names: Sequence[str] | None = None  # bound to these (the same object: no check)
        self._program: tuple[str, ...] = ()
        self._index: slice | np.ndarray = slice(0)
        self._jacobian = np.zeros((len(self.names), 0))

    def __call__(self, joint_names: Sequence[str], q: np.ndarray, /) -> Features:
        if joint_names is not self._joint_names:
            self._bind(joint_names)
        return q[self._index].copy(), self._jacobian

    def _bind(self, joint_names: Sequence[str]) -> None:
        program = tuple(joint_names)
        if program != self._program or self._joint_names is None:
            index = {n: i for i, n in enumerate(program)}
            missing = [n for n in self.names if n not in index]
            if missing:
                raise KeyError(f'no joints {missing} in the program; joints: {program}')
            self._index = compact_index([index[n] for n in self.names])
            self._jacobian = np.eye(len(program))[self._index]
            self._program = program
        self._joint_names = joint_names
