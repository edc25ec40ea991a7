"""Scene (world model): robots and objects placed in the world, the program-wide joint vector, and
composable relative poses and Jacobians between any two object frames (paper §4.1 "Scene").

Frames are addressed ``"robot/frame"``, ``"object/frame"`` (``"object"`` alone is its origin) or
``"world"``. The program-wide joint vector is the concatenation of all robots' velocity
coordinates in the order the robots were added.

Geometric semantics of ``relative_jacobian(o1, o2)``: it maps the program qdot to the twist of
o2 relative to o1, *expressed in o1*, with o2's origin as reference point, i.e. the rows are
``[d/dt p_{o1,o2} ; omega_{o1,o2}]`` with ``p_{o1,o2}`` the position of o2 in o1 coordinates and
``omega`` the angular velocity of o2 relative to o1 in o1 coordinates. Its first three rows are
the exact time derivative of ``relative_pose(o1, o2).translation``; ``R_{o1,o2}`` evolves as
``d/dt R = [omega]x R``.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence

import numpy as np
import pinocchio as pin

from .objects import Object
from .robot import Robot

__all__ = ['Scene']

_WORLD = pin.SE3.Identity()


class _Frame:
    """A resolved frame address: a robot frame (robot, Pinocchio id, columns) or a pose getter."""

    __slots__ = ('robot', 'fid', 'columns', 'obj', 'name')

    def __init__(self, robot: Robot | None, fid: int, columns: slice | None,
                 obj: Object | None, name: str) -> None:
        self.robot, self.fid, self.columns, self.obj, self.name = robot, fid, columns, obj, name

    def pose(self) -> pin.SE3:
        if self.robot is not None:
            return self.robot.data.oMf[self.fid]
        return _WORLD if self.obj is None else self.obj.frame_pose(self.name)


class Scene:
    """Robots (with their base placements) and Objects in one world frame."""

    def __init__(self, *, robots: Sequence[Robot] = (), objects: Sequence[Object] = ()) -> None:
        self.robots: dict[str, Robot] = {}
        self.objects: dict[str, Object] = {}
        self.version = 0
        self._slices: dict[str, slice] = {}
        self._frames: dict[str, _Frame] = {}
        self._reindex()
        for robot in robots:
            self.add_robot(robot)
        for obj in objects:
            self.add_object(obj)

    # -- composition ---------------------------------------------------------------------------
    def add_robot(self, robot: Robot) -> None:
        if robot.name in self.robots or robot.name in self.objects or robot.name == 'world':
            raise ValueError(f'Scene already has an entity named {robot.name!r}')
        clash = set(robot.joint_names) & set(self.joint_names)
        if clash:
            raise ValueError(f'Robot {robot.name!r}: joint names {sorted(clash)} already in the '
                             'Scene (use Robot(prefix=...))')
        self.robots[robot.name] = robot
        self._reindex()

    def add_object(self, obj: Object) -> None:
        if obj.name in self.robots or obj.name in self.objects or obj.name == 'world':
            raise ValueError(f'Scene already has an entity named {obj.name!r}')
        self.objects[obj.name] = obj
        self._reindex()

    def remove(self, name: str) -> None:
        """Remove a robot or an object (run-time re-composition)."""
        if self.robots.pop(name, None) is None and self.objects.pop(name, None) is None:
            raise KeyError(f'Scene has no robot or object {name!r}')
        self._reindex()

    def _reindex(self) -> None:
        start = 0
        self._slices.clear()
        for name, robot in self.robots.items():
            self._slices[name] = slice(start, start + robot.nv)
            start += robot.nv
        robots = list(self.robots.values())
        self.joint_names: list[str] = [n for r in robots for n in r.joint_names]
        self.nv = start

        def cat(attr: str) -> np.ndarray:
            return np.concatenate([getattr(r, attr) for r in robots]) if robots else np.zeros(0)

        self.lower, self.upper = cat('lower'), cat('upper')
        self.velocity_limit = cat('velocity_limit')
        self.q = cat('positions')
        self._frames.clear()
        self.version += 1

    def robot_slice(self, name: str) -> slice:
        """Columns of robot ``name`` in the program-wide joint vector."""
        return self._slices[name]

    # -- state ---------------------------------------------------------------------------------
    def set_positions(self, names: Sequence[str], values: Sequence[float]) -> None:
        """Set joint positions by name on every robot (unknown names ignored)."""
        for robot in self.robots.values():
            robot.set_positions(names, values)

    def set_position_vector(self, q: np.ndarray) -> None:
        """Set all robots from a program-wide position vector (``joint_names`` order)."""
        for name, robot in self.robots.items():
            robot.set_position_vector(q[self._slices[name]])

    def integrate(self, qdot: np.ndarray, dt: float) -> None:
        """Advance every robot by its part of the program-wide velocity over ``dt``."""
        for name, robot in self.robots.items():
            robot.integrate(qdot[self._slices[name]], dt)

    def update(self, t: float | None = None) -> None:
        """Forward kinematics of all robots, trajectories of moving objects, and ``q``."""
        for name, robot in self.robots.items():
            robot.update()
            self.q[self._slices[name]] = robot.positions
        for obj in self.objects.values():
            obj.update(t)

    # -- geometry ------------------------------------------------------------------------------
    def frame(self, address: str) -> _Frame:
        """Resolve ``"robot/frame"``, ``"object/frame"``, ``"object"`` or ``"world"`` (cached)."""
        resolved = self._frames.get(address)
        if resolved is not None:
            return resolved
        owner, _, name = address.partition('/')
        if owner == 'world' and not name:
            resolved = _Frame(None, 0, None, None, 'world')
        elif owner in self.robots:
            robot = self.robots[owner]
            resolved = _Frame(robot, robot.frame_id(name), self._slices[owner], None, name)
        elif owner in self.objects:
            obj = self.objects[owner]
            name = name or 'origin'
            if not obj.has_frame(name):
                raise KeyError(f'Object {owner!r} has no frame {name!r}; frames: {obj.frame_names}')
            resolved = _Frame(None, 0, None, obj, name)
        else:
            raise KeyError(f'Scene has no robot or object {owner!r} (frame {address!r}); '
                           f'robots: {list(self.robots)}, objects: {list(self.objects)}')
        self._frames[address] = resolved
        return resolved

    def pose(self, frame: str) -> pin.SE3:
        """World pose of a frame (a copy)."""
        return pin.SE3(self.frame(frame).pose())

    def relative_pose(self, o1: str, o2: str) -> pin.SE3:
        """Pose of o2 expressed in o1: ``T_{o1,o2} = T_{w,o1}^-1 T_{w,o2}``."""
        return self.frame(o1).pose().actInv(self.frame(o2).pose())

    def relative_jacobian(self, o1: str, o2: str, *, expressed: str = 'o1') -> np.ndarray:
        """(6, nv) map from program qdot to the twist of o2 relative to o1, reference point o2's
        origin, expressed in o1 (default, see the module docstring) or in o2 (``'o2'``: the
        body twist of o2 relative to o1)."""
        f1, f2 = self.frame(o1), self.frame(o2)
        T1 = f1.pose()
        if f1.robot is None and f2.robot is not None and f2.robot.nv == self.nv:
            J = pin.getFrameJacobian(f2.robot.model, f2.robot.data, f2.fid,
                                     pin.LOCAL_WORLD_ALIGNED)
        else:
            J = np.zeros((6, self.nv))
            if f2.robot is not None:
                J[:, f2.columns] = pin.getFrameJacobian(f2.robot.model, f2.robot.data, f2.fid,
                                                        pin.LOCAL_WORLD_ALIGNED)
            if f1.robot is not None:
                J1 = pin.getFrameJacobian(f1.robot.model, f1.robot.data, f1.fid,
                                          pin.LOCAL_WORLD_ALIGNED)
                d = f2.pose().translation - T1.translation
                J[:3, f1.columns] += pin.skew(d) @ J1[3:] - J1[:3]
                J[3:, f1.columns] -= J1[3:]
        R = T1.rotation if expressed == 'o1' else f2.pose().rotation
        return np.matmul(R.T, J.reshape(2, 3, -1)).reshape(6, -1)

    def joint_indices(self, names: Iterable[str]) -> np.ndarray:
        """Indices of joints in the program-wide joint vector."""
        index = {n: i for i, n in enumerate(self.joint_names)}
        missing = [n for n in names if n not in index]
        if missing:
            raise KeyError(f'Scene has no joints {missing}; joints: {self.joint_names}')
        return np.array([index[n] for n in names], dtype=int)
