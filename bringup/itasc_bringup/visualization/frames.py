"""The frame tree of an application for TF (REP 105: one ``world`` root), computed with Pinocchio
from the same models the Scene uses (paper §4.1 "Scene": robots and objects placed in one world,
object frames on robot links and on objects).

Names are those robot_state_publisher would give with ``frame_prefix: <robot>/``: ``panda/panda_link3``;
an object frame on a robot is ``<robot>/<frame>``, an object's origin ``<object>``, its frames
``<object>/<frame>`` — exactly how Tasks address their o1 and o2 frames. Like robot_state_publisher,
a link hangs on its parent link, fixed joints are static (``/tf_static``) and the others follow the
joint state (``/tf``), and the robot's root link hangs on ``world`` at the robot's placement
(moving with the base joint of a mobile robot).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin
from itasc_core.itasc.robot import Robot, se3

from ..model.schema import Application
from .description import link_tree

__all__ = ['WORLD', 'Edge', 'RobotFrames', 'FrameTree', 'quaternion_xyzw']

WORLD = 'world'


@dataclass(frozen=True)
class Edge:
    """One transform: ``child`` in ``parent`` coordinates."""

    parent: str
    child: str
    pose: pin.SE3


class RobotFrames:
    """The TF edges of one robot: static ones once, moving ones per joint state."""

    def __init__(self, robot, description: str) -> None:
        self.name = robot.name
        self.model = Robot(robot.name, description, base=robot.base, xyz=robot.xyz, rpy=robot.rpy)
        self.root, parents = link_tree(description)
        self._prefix = f'{robot.name}/'
        frames = self.model.model
        self._ids = {link: frames.getFrameId(link, pin.BODY) for link in [self.root, *parents]}
        self._moving = [(p, c) for c, (p, fixed) in parents.items() if not fixed]
        self._fixed = [(p, c) for c, (p, fixed) in parents.items() if fixed]
        self._offsets = [(f.link, f.name, se3(f.xyz, f.rpy)) for f in robot.frames]
        for f in robot.frames:
            self.model.add_frame(f.name, f.link, xyz=f.xyz, rpy=f.rpy)
        self.mobile = robot.base != 'fixed'
        pin.framesForwardKinematics(frames, self.model.data, self.model.q)

    def _edge(self, parent: str, child: str) -> Edge:
        oMf = self.model.data.oMf
        return Edge(self._prefix + parent, self._prefix + child,
                    oMf[self._ids[parent]].actInv(oMf[self._ids[child]]))

    def _root(self) -> Edge:
        return Edge(WORLD, self._prefix + self.root, pin.SE3(self.model.data.oMf[self._ids[self.root]]))

    def static(self) -> list[Edge]:
        """Fixed joints, object frames on links, and the placement of a fixed base."""
        edges = [self._edge(p, c) for p, c in self._fixed]
        edges += [Edge(self._prefix + link, self._prefix + name, pose) for link, name, pose in self._offsets]
        return edges + ([] if self.mobile else [self._root()])

    def moving(self, names, positions) -> list[Edge]:
        """The moving joints (and a mobile base) at the joint state ``names``/``positions``."""
        self.model.set_positions(names, positions)
        pin.framesForwardKinematics(self.model.model, self.model.data, self.model.q)
        edges = [self._edge(p, c) for p, c in self._moving]
        return edges + ([self._root()] if self.mobile else [])

    def world_pose(self, link: str) -> pin.SE3:
        """World pose of a link or object frame at the last joint state (for markers)."""
        return pin.SE3(self.model.data.oMf[self.model.frame_id(link)])


@dataclass
class FrameTree:
    """All frames of an application: robots (see :class:`RobotFrames`) and objects."""

    robots: dict[str, RobotFrames]
    #: object name -> placement in the world (fixed objects), or None while unknown (moving, sensed)
    objects: dict[str, pin.SE3 | None]
    offsets: dict[str, list[tuple[str, pin.SE3]]] = field(default_factory=dict)

    @classmethod
    def of(cls, app: Application, descriptions: dict[str, str]) -> 'FrameTree':
        sensed = {s.object for s in app.sensors}
        robots = {r.name: RobotFrames(r, descriptions[r.name]) for r in app.program.robots}
        objects = {o.name: None if (o.motion or o.name in sensed) else se3(o.xyz, o.rpy)
                   for o in app.program.objects}
        offsets = {o.name: [(f.name, se3(f.xyz, f.rpy)) for f in o.frames] for o in app.program.objects}
        return cls(robots=robots, objects=objects, offsets=offsets)

    def static(self) -> list[Edge]:
        edges = [e for r in self.robots.values() for e in r.static()]
        edges += [Edge(WORLD, name, pose) for name, pose in self.objects.items() if pose is not None]
        edges += [Edge(name, f'{name}/{frame}', pose) for name, frames in self.offsets.items()
                  for frame, pose in frames]
        return edges

    def frame_pose(self, address: str) -> pin.SE3 | None:
        """World pose of a Scene frame address (``robot/frame``, ``object[/frame]``, ``world``),
        or None when unknown yet."""
        if address == WORLD:
            return pin.SE3.Identity()
        owner, _, frame = address.partition('/')
        if owner in self.robots:
            return self.robots[owner].world_pose(frame)
        origin = self.objects.get(owner)
        if origin is None or not frame:
            return origin
        return origin * dict(self.offsets[owner])[frame]

    def object_pose_from(self, address: str, other: str, relative: pin.SE3) -> pin.SE3 | None:
        """World pose of the origin of the object of ``address`` (its frame o1), given the pose
        ``relative`` of frame ``other`` (o2) in it, when ``other``'s world pose is known."""
        other_pose = self.frame_pose(other)
        if other_pose is None:
            return None
        owner, _, frame = address.partition('/')
        offset = dict(self.offsets[owner])[frame] if frame else pin.SE3.Identity()
        return other_pose * relative.inverse() * offset.inverse()


def quaternion_xyzw(rotation: np.ndarray) -> tuple[float, float, float, float]:
    q = pin.Quaternion(rotation)
    return float(q.x), float(q.y), float(q.z), float(q.w)
