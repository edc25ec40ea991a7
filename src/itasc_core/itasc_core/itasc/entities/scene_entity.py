"""SceneEntity: the world model of a constraint-based program (paper §4.1 "Scene", §4.2).

It owns the :class:`itasc_core.itasc.Scene` math object, built from its parameters: the robots
(URDF, base type, placement in the world, object frames on links), the objects (placement,
object frames, whether a Sensor measures their pose) and the *relations* — the pairs of object
frames between which Tasks are defined (the paper: the Scene knows "between which object frames
tasks are defined"). Every tick it takes each robot's joint state and each sensed object's pose
from its input ports, computes forward kinematics once, and writes on its output ports

* ``joint_state``: the program-wide joint positions (``sensor_msgs/JointState``, Scene order);
* ``relation_<name>``: per relation, the pose of o2 relative to o1 expressed in o1 as
  ``[p; log3(R)]`` with its Jacobian on the program-wide joint velocities (a labelled table,
  see :mod:`.messages`), geometric semantics ``Relation(o2|o1)@o1``.

A measured pose that is not finite or whose quaternion is zero raises ``e_emergency`` (Safety) and
nothing is written that tick; any other quaternion is normalised.

Parameters are lists of YAML flow mappings (ROS parameters hold no nested structures), e.g.::

    robots:    ['{name: panda, urdf: /abs/panda.urdf, base: fixed, xyz: [0, 0, 0],
                 frames: {tcp: {link: panda_hand_tcp}}}']
    objects:   ['{name: target, xyz: [0.5, 0, 0.2], frames: {grasp: {rpy: [3.14159, 0, 0]}},
                 sensed: false}']
    relations: ['{name: ApproachObject, o1: target/grasp, o2: panda/tcp}']
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pinocchio as pin
import yaml
from geometry_msgs.msg import PoseStamped
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray

from ...communication.ports import PortSpec
from ...computation.functional_entity import FunctionalEntity
from ..objects import Object, periodic_translation
from ..robot import Robot
from ..scene import Scene
from .messages import stamp, table_msg
from .robot_entity import joint_positions

__all__ = ['SceneEntity', 'PROGRAM_JOINTS', 'relation_semantics', 'object_pose', 'entries']

#: Semantics of the program-wide joint position vector.
PROGRAM_JOINTS = 'JointPositions(program)'
FEATURES = ('x', 'y', 'z', 'rx', 'ry', 'rz')


def relation_semantics(o1: str, o2: str) -> str:
    return f'Relation({o2}|{o1})@{o1}'


def object_pose(obj: str) -> str:
    return f'Pose({obj}|world)@world'


def entries(values: list[str]) -> list[dict[str, Any]]:
    """Decode a list-of-YAML-flow-mappings parameter (empty strings are placeholders)."""
    return [yaml.safe_load(v) for v in values if v]


class SceneEntity(FunctionalEntity):
    """Robots and objects in one world; relative poses and Jacobians between object frames."""

    PARAMETERS = {'robots': [''], 'objects': [''], 'relations': ['']}

    @classmethod
    def port_specs(cls, params: dict[str, Any]) -> list[PortSpec]:
        specs = [PortSpec(name=f"joint_state_{r['name']}", direction='input', msg_type=JointState,
                          type='joint_state', semantics=joint_positions(r['name']))
                 for r in entries(params['robots'])]
        specs += [PortSpec(name=f"pose_{o['name']}", direction='input', msg_type=PoseStamped,
                           type='pose', semantics=object_pose(o['name']))
                  for o in entries(params['objects']) if o.get('sensed')]
        specs.append(PortSpec(name='joint_state', direction='output', msg_type=JointState,
                              type='joint_state', semantics=PROGRAM_JOINTS))
        specs += [PortSpec(name=f"relation_{r['name']}", direction='output', msg_type=Float64MultiArray,
                           type='relation', semantics=relation_semantics(r['o1'], r['o2']))
                  for r in entries(params['relations'])]
        return specs

    def configure(self, params: dict[str, Any]) -> None:
        scene = Scene()
        for r in entries(params['robots']):
            robot = Robot(r['name'], r['urdf'], base=r.get('base', 'fixed'),
                          xyz=r.get('xyz', (0, 0, 0)), rpy=r.get('rpy', (0, 0, 0)))
            for frame, spec in (r.get('frames') or {}).items():
                robot.add_frame(frame, spec['link'], xyz=spec.get('xyz', (0, 0, 0)),
                                rpy=spec.get('rpy', (0, 0, 0)))
            scene.add_robot(robot)
        self.sensed: list[str] = []
        for o in entries(params['objects']):
            xyz, rpy, motion = o.get('xyz', (0, 0, 0)), o.get('rpy', (0, 0, 0)), o.get('motion')
            trajectory = None if motion is None else periodic_translation(
                xyz=xyz, rpy=rpy, amplitude=motion['amplitude'], period=motion['period'])
            obj = Object(o['name'], xyz=xyz, rpy=rpy, trajectory=trajectory)
            for frame, spec in (o.get('frames') or {}).items():
                obj.add_frame(frame, xyz=spec.get('xyz', (0, 0, 0)), rpy=spec.get('rpy', (0, 0, 0)))
            scene.add_object(obj)
            if o.get('sensed'):
                self.sensed.append(o['name'])
        self.relations = [(r['name'], r['o1'], r['o2']) for r in entries(params['relations'])]
        for _, o1, o2 in self.relations:  # unknown frames fail at configuration, not while running
            scene.frame(o1), scene.frame(o2)
        self.scene = scene
        self._columns = ('value', *scene.joint_names)

    def update(self, t: float) -> None:
        states = [self.inputs[f'joint_state_{name}'].latest for name in self.scene.robots]
        if any(s is None for s in states):
            return  # the world is not known before every robot has reported its joints
        for state in states:
            self.scene.set_positions(state.name, state.position)
        for name in self.sensed:
            msg = self.inputs[f'pose_{name}'].latest
            if msg is None:
                continue
            pose = _se3(msg.pose)
            if pose is None:  # a broken measurement is not a place to move to
                self.raise_event('e_emergency', priority=True,
                                 detail=f'{name}: measured pose not finite or its quaternion zero')
                return
            self.scene.objects[name].set_pose(pose)
        self.scene.update(t)
        out = JointState(name=list(self.scene.joint_names), position=self.scene.q.tolist())
        out.header.stamp = stamp(t)
        self.outputs['joint_state'].write(out)
        for name, o1, o2 in self.relations:
            pose = self.scene.relative_pose(o1, o2)
            values = np.column_stack([np.concatenate([pose.translation, pin.log3(pose.rotation)]),
                                      self.scene.relative_jacobian(o1, o2)])
            self.outputs[f'relation_{name}'].write(table_msg(FEATURES, self._columns, values, rotation=3))

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
