"""VKCEntity: the Virtual Kinematic Chain of a Task (paper §4.1 "VKC", §4.2, Fig. 2).

Builds the chain of its Task's type (:mod:`itasc_tasks.task_types`). Input: for a chain between the
Task's object frames o1 and o2 the Scene's relation between them (``relation``, semantics
``Relation(o2|o1)@o1``); for a joint chain the program's joint positions (``joint_state``).
Output ``features``: the feature coordinates chi_f with their Jacobian on the program-wide joint
velocities (``itasc_msgs/Features``, semantics ``Features(<task>)``), stamped with its input's
stamp: the Scene's tick whose configuration they describe (in another process than the Scene's, the
newest relation there may be of an earlier tick than the one computing).

The entity knows nothing but its ports (boundary of knowledge, paper §3.1): it hands the chain
(:mod:`itasc_tasks.vkc`) the arrays of its input and writes what the chain returns.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from itasc_msgs.msg import Features
from sensor_msgs.msg import JointState

from itasc_core.communication.ports import PortSpec
from itasc_core.itasc.coordinates import features_pose
from itasc_core.computation.functional_entity import FunctionalEntity
from itasc_core.computation.parameters import ParameterModel
from itasc_core.itasc.entities.messages import FeaturesSample
from itasc_core.itasc.entities.scene_entity import PROGRAM_JOINTS, relation_semantics
from itasc_core.kinds import with_kind

from ..task_types import TASK_TYPES
from .common import TaskName, task_port

__all__ = ['VKCEntity']


class VKCEntity(FunctionalEntity):
    """Feature coordinates chi_f between two object frames (or of joints) and their Jacobian."""

    class Parameters(ParameterModel):
        task: TaskName = 'task'
        """The Task it belongs to."""
        type: str = 'cartesian'
        """The chain: a registered task type (its parameters follow)."""

    @classmethod
    def parameter_model(cls, values: Mapping[str, Any]) -> type[ParameterModel]:
        return with_kind(cls.Parameters, TASK_TYPES, field='type', values=values)

    @classmethod
    def port_specs(cls, params: Any) -> list[PortSpec]:
        if TASK_TYPES[params.type].reads == 'joints':
            source = PortSpec(name='joint_state', direction='input', msg_type=JointState,
                              type='joint_state', semantics=PROGRAM_JOINTS)
        else:
            source = PortSpec(name='relation', direction='input', msg_type=Features,
                              type='relation', semantics=relation_semantics(params.o1, params.o2))
        return [source, task_port('features', 'output', 'Features', params.task)]

    def configure(self, params: Any) -> None:
        kind = TASK_TYPES[params.type]
        self.vkc = kind.chain(params)
        self.reads = kind.reads

    def update(self, t: float) -> None:
        vkc = self.vkc
        if self.reads == 'joints':
            joints = self.inputs['joint_state'].latest
            if joints is None:
                return
            joint_names, stamp = joints.name, joints.t
            features, jacobian = vkc(joint_names, joints.position)
        else:
            relation = self.inputs['relation'].latest
            if relation is None:
                return
            joint_names, stamp = relation.joint_names, relation.t
            pose = relation.pose if relation.pose is not None else features_pose(relation.value,
                                                                                 coordinates='xyz_log3')
            features, jacobian = vkc(pose, relation.jacobian)
        self.outputs['features'].write(FeaturesSample(stamp, vkc.names, joint_names, features, jacobian, vkc.rotation))

