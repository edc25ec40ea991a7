"""SceneEntity: the world model of a constraint-based program (paper §4.1 "Scene", §4.2).

It owns the :class:`itasc_core.itasc.Scene` math object, built from its parameters: the robots
(URDF, base type, placement in the world, object frames on links), the objects (placement,
object frames, whether a Sensor measures their pose) and the *relations* — the pairs of object
frames between which Tasks are defined (the paper: the Scene knows "between which object frames
tasks are defined"). Every tick it takes each robot's joint state and each sensed object's pose
from its input ports, computes forward kinematics once, and writes on its output ports

* ``joint_state``: the program-wide joint positions (``sensor_msgs/JointState``, Scene order);
* ``relation_<name>``: per relation, the pose of o2 relative to o1 expressed in o1 as
  ``[p; log3(R)]`` (names x y z rx ry rz) with its Jacobian on the program-wide joint velocities
  (``itasc_msgs/Features``, see :mod:`.messages`), geometric semantics ``Relation(o2|o1)@o1``.

A measured pose that is not finite or whose quaternion is zero raises ``e_emergency`` (Safety) and
nothing is written that tick; any other quaternion is normalised.

Its parameters are typed (:class:`SceneEntity.Parameters`): robots, objects and relations by name,
declared as ROS parameters ``robots.<robot>.urdf``, ``objects.<object>.frames.<frame>.xyz``,
``relations.<Task>.o1``, ... What the program's structure rests on is read-only (a robot's URDF,
base and frame links, whether an object is sensed, the relations: the Tasks and the Solver were
built for them); placements are not (an object moved, a robot's base placed anew).
"""

from __future__ import annotations

from typing import Literal

import numpy as np
import pinocchio as pin
from geometry_msgs.msg import PoseStamped
from itasc_msgs.msg import Features
from sensor_msgs.msg import JointState
from pydantic import Field, FiniteFloat

from ...communication.event_names import SAFETY_EVENT
from ...communication.ports import PortSpec
from ...computation.functional_entity import FunctionalEntity
from ...computation.parameters import ParameterModel
from ..coordinates import POSE_FEATURES
from ..objects import Object, periodic_translation
from ..robot import Robot
from ..scene import Scene
from .messages import FeaturesSample, JointSample
from .robot_entity import joint_positions

__all__ = ['SceneEntity', 'PROGRAM_JOINTS', 'relation_semantics', 'object_pose', 'Placement', 'ObjectMotion']

#: Semantics of the program-wide joint position vector.
PROGRAM_JOINTS = 'JointPositions(program)'


def relation_semantics(o1: str, o2: str) -> str:
    return f'Relation({o2}|{o1})@{o1}'


def object_pose(obj: str) -> str:
    return f'Pose({obj}|world)@world'


Vec3 = tuple[FiniteFloat, FiniteFloat, FiniteFloat]


class Placement(ParameterModel):
    """A pose: translation [m] and roll-pitch-yaw [rad] (URDF convention)."""

    xyz: Vec3 = (0.0, 0.0, 0.0)
    """Translation [m]."""
    rpy: Vec3 = (0.0, 0.0, 0.0)
    """Roll, pitch, yaw [rad] (URDF convention)."""


class ObjectMotion(ParameterModel):
    """A moving object's trajectory: oscillating about its placement, per axis."""

    amplitude: Vec3
    """Amplitude per axis x, y, z [m]."""
    period: float = Field(gt=0)
    """Period of the oscillation [s]."""


class LinkFrame(Placement):
    """An object frame on a robot link, offset from the link."""

    link: str = Field(min_length=1, frozen=True)
    """The URDF link it is fixed to."""


class SceneRobot(Placement):
    """A robot of the Scene, placed in the world."""

    urdf: str = Field(min_length=1, frozen=True)
    """Its URDF file (absolute path)."""
    base: Literal['fixed', 'planar', 'free_flyer'] = Field(default='fixed', frozen=True)
    """Its base: fixed, or a mobile base's joints."""
    frames: dict[str, LinkFrame] = Field(default_factory=dict)
    """Its object frames by name."""


class SceneObject(Placement):
    """An object of the Scene, at its placement or moving."""

    frames: dict[str, Placement] = Field(default_factory=dict)
    """Its frames by name, relative to it."""
    sensed: bool = Field(default=False, frozen=True)
    """Whether a Sensor measures its pose (input ``pose_<object>``)."""
    motion: ObjectMotion | None = None
    """A known motion about the placement."""


class Relation(ParameterModel):
    """A pair of object frames a Task is defined between."""

    o1: str = Field(min_length=1, frozen=True)
    """The first frame (``robot/frame``, ``object/frame``, ``object`` or ``world``)."""
    o2: str = Field(min_length=1, frozen=True)
    """The second frame."""


class SceneEntity(FunctionalEntity):
    """Robots and objects in one world; relative poses and Jacobians between object frames."""

    class Parameters(ParameterModel):
        robots: dict[str, SceneRobot] = Field(default_factory=dict)
        """The robots by name, in the order of the program's joints."""
        objects: dict[str, SceneObject] = Field(default_factory=dict)
        """The objects by name."""
        relations: dict[str, Relation] = Field(default_factory=dict)
        """The relations between object frames, by the name of the Task they serve."""

    @classmethod
    def port_specs(cls, params: Parameters) -> list[PortSpec]:
        specs = [PortSpec(name=f'joint_state_{name}', direction='input', msg_type=JointState,
                          type='joint_state', semantics=joint_positions(name)) for name in params.robots]
        specs += [PortSpec(name=f'pose_{name}', direction='input', msg_type=PoseStamped,
                           type='pose', semantics=object_pose(name))
                  for name, o in params.objects.items() if o.sensed]
        specs.append(PortSpec(name='joint_state', direction='output', msg_type=JointState,
                              type='joint_state', semantics=PROGRAM_JOINTS))
        specs += [PortSpec(name=f'relation_{name}', direction='output', msg_type=Features,
                           type='relation', semantics=relation_semantics(r.o1, r.o2))
                  for name, r in params.relations.items()]
        return specs

    def configure(self, params: Parameters) -> None:
        scene = Scene()
        for name, r in params.robots.items():
            robot = Robot(name, r.urdf, base=r.base, xyz=r.xyz, rpy=r.rpy)
            for frame, spec in r.frames.items():
                robot.add_frame(frame, spec.link, xyz=spec.xyz, rpy=spec.rpy)
            scene.add_robot(robot)
        self.sensed: list[str] = []
        for name, o in params.objects.items():
            trajectory = None if o.motion is None else periodic_translation(
                xyz=o.xyz, rpy=o.rpy, amplitude=o.motion.amplitude, period=o.motion.period)
            obj = Object(name, xyz=o.xyz, rpy=o.rpy, trajectory=trajectory)
            for frame, placement in o.frames.items():
                obj.add_frame(frame, xyz=placement.xyz, rpy=placement.rpy)
            scene.add_object(obj)
            if o.sensed:
                self.sensed.append(name)
        self.relations = [(name, r.o1, r.o2) for name, r in params.relations.items()]
        for _, o1, o2 in self.relations:  # unknown frames fail at configuration, not while running
            scene.frame(o1), scene.frame(o2)
        self.scene = scene
        self._joint_names = tuple(scene.joint_names)
        self._robots = [(self.inputs[f'joint_state_{name}'], robot, tuple(robot.joint_names))
                        for name, robot in scene.robots.items()]
        # one computation per pair of frames, whichever Tasks read it (Retreat and ApproachObject both
        # relate the TCP to the grasp frame)
        pairs: dict[tuple[str, str], list] = {}
        for name, o1, o2 in self.relations:
            pairs.setdefault((o1, o2), []).append(self.outputs[f'relation_{name}'])
        self._relations = [(o1, o2, outputs) for (o1, o2), outputs in pairs.items()]

    def update(self, t: float) -> None:
        for port, _, _ in self._robots:
            if port.latest is None:
                return  # the world is not known before every robot has reported its joints
        for port, robot, joints in self._robots:
            state = port.latest
            if state.name == joints:  # the Robot entity's order: no lookup by name
                robot.set_position_vector(state.position)
            else:
                robot.set_positions(state.name, state.position)
        for name in self.sensed:
            msg = self.inputs[f'pose_{name}'].latest
            if msg is None:
                continue
            pose = _se3(msg.pose)
            if pose is None:  # a broken measurement is not a place to move to
                self.raise_event(SAFETY_EVENT, priority=True,
                                 detail=f'{name}: measured pose not finite or its quaternion zero')
                return
            self.scene.objects[name].set_pose(pose)
        scene = self.scene
        scene.update(t)
        joints = self._joint_names
        self.outputs['joint_state'].write(JointSample(t, joints, scene.q.copy()))
        for o1, o2, outputs in self._relations:
            pose = scene.relative_pose(o1, o2)
            sample = FeaturesSample(t, POSE_FEATURES, joints, None, scene.relative_jacobian(o1, o2), rotation=3,
                                    pose=pose)  # the value (xyz_log3) computed if read
            for output in outputs:
                output.write(sample)

    def fault_persists(self) -> str | None:
        """Before a recovery from Safety: is a sensed pose still not finite (or its quaternion zero)?"""
        broken = [name for name in self.sensed if _broken(self.inputs[f'pose_{name}'].latest)]
        return f'measured pose of {", ".join(broken)} not finite or its quaternion zero' if broken else None


def _broken(msg) -> bool:
    return msg is not None and _se3(msg.pose) is None


def _se3(pose) -> pin.SE3 | None:
    """A ``geometry_msgs/Pose`` as SE3, its quaternion normalised (scaled first, so that neither a
    tiny nor a huge one under- or overflows); None if a value is not finite or the quaternion zero."""
    o, p = pose.orientation, pose.position
    q, xyz = np.array([o.x, o.y, o.z, o.w]), np.array([p.x, p.y, p.z])
    if not (np.isfinite(q).all() and np.isfinite(xyz).all()) or not q.any():
        return None
    q /= np.abs(q).max()
    q /= np.linalg.norm(q)
    return pin.SE3(pin.Quaternion(q[3], q[0], q[1], q[2]).toRotationMatrix(), xyz)
