"""VKCEntity: the Virtual Kinematic Chain of a Task (paper §4.1 "VKC", §4.2, Fig. 2).

Wraps the chains of :mod:`itasc_tasks.vkc`. Input: for a ``cartesian`` or ``distance`` chain the
Scene's relation between the Task's object frames o1 and o2 (``relation``, semantics
``Relation(o2|o1)@o1``); for a ``joint`` chain the program's joint positions (``joint_state``).
Output ``features``: the feature coordinates chi_f with their Jacobian on the program-wide joint
velocities (a labelled table, semantics ``Features(<task>)``).

The math chains read a Scene; here they read a *view* built from the input port, so the entity
knows nothing but its ports (boundary of knowledge, paper §3.1).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pinocchio as pin
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray

from itasc_core.communication.ports import PortSpec
from itasc_core.computation.functional_entity import FunctionalEntity
from itasc_core.itasc.entities.messages import Table, read_table, table_msg
from itasc_core.itasc.entities.scene_entity import PROGRAM_JOINTS, relation_semantics

from ..vkc import CartesianVKC, DistanceVKC, JointVKC
from .common import names, table_port

__all__ = ['VKCEntity']

TYPES = ('cartesian', 'distance', 'joint')


class _RelationView:
    """What a Cartesian or distance chain reads of a Scene, from one relation table."""

    def __init__(self, table: Table) -> None:
        value = table.column('value')
        self.pose = pin.SE3(pin.exp3(value[3:6]), value[0:3].copy())
        self.jacobian = table.matrix()

    def relative_pose(self, o1: str, o2: str) -> pin.SE3:
        return self.pose

    def relative_jacobian(self, o1: str, o2: str, *, expressed: str = 'o1') -> np.ndarray:
        """The relation's Jacobian, expressed in o1 (as the Scene sends it) or in o2."""
        if expressed == 'o2':
            Rt = self.pose.rotation.T
            return np.vstack([Rt @ self.jacobian[:3], Rt @ self.jacobian[3:]])
        return self.jacobian.copy()


class _JointView:
    """What a joint chain reads of a Scene, from the program's joint state."""

    def __init__(self) -> None:
        self.version = 0
        self.joint_names: list[str] = []
        self.q = np.zeros(0)

    def read(self, msg: JointState) -> None:
        if list(msg.name) != self.joint_names:
            self.joint_names = list(msg.name)
            self.version += 1
        self.q = np.asarray(msg.position, dtype=float)

    @property
    def nv(self) -> int:
        return len(self.joint_names)

    def joint_indices(self, joints) -> np.ndarray:
        index = {n: i for i, n in enumerate(self.joint_names)}
        missing = [n for n in joints if n not in index]
        if missing:
            raise KeyError(f'no joints {missing} in the program; joints: {self.joint_names}')
        return np.array([index[n] for n in joints], dtype=int)


class VKCEntity(FunctionalEntity):
    """Feature coordinates chi_f between two object frames (or of joints) and their Jacobian."""

    PARAMETERS = {
        'task': 'task',
        'type': 'cartesian',        # cartesian | distance | joint
        'o1': 'world',
        'o2': 'world',
        'coordinates': 'xyz_log3',  # cartesian: xyz_log3 | log6
        'normal': [0.0, 0.0, 0.0],  # distance: plane normal in o1 (zero: point-point distance)
        'joints': [''],             # joint: the joints (none: all of the program's)
    }

    @classmethod
    def port_specs(cls, params: dict[str, Any]) -> list[PortSpec]:
        if params['type'] == 'joint':
            source = PortSpec(name='joint_state', direction='input', msg_type=JointState,
                              type='joint_state', semantics=PROGRAM_JOINTS)
        else:
            source = PortSpec(name='relation', direction='input', msg_type=Float64MultiArray,
                              type='relation', semantics=relation_semantics(params['o1'], params['o2']))
        return [source, table_port('features', 'output', 'Features', params['task'])]

    def validate_parameters(self, params: dict[str, Any]) -> str | None:
        if params['type'] not in TYPES:
            return f"type must be one of {TYPES}, got {params['type']!r}"
        return None

    def configure(self, params: dict[str, Any]) -> None:
        kind = params['type']
        if kind == 'cartesian':
            self.vkc = CartesianVKC(params['o1'], params['o2'], coordinates=params['coordinates'])
        elif kind == 'distance':
            normal = params['normal'] if any(params['normal']) else None
            self.vkc = DistanceVKC(params['o1'], params['o2'], normal=normal)
        else:
            self.vkc = JointVKC(names(params['joints']) or None)
            self._joints = _JointView()
        self.kind = kind

    def update(self, t: float) -> None:
        if self.kind == 'joint':
            msg = self.inputs['joint_state'].latest
            if msg is None:
                return
            self._joints.read(msg)
            view, joint_names = self._joints, self._joints.joint_names
        else:
            msg = self.inputs['relation'].latest
            if msg is None:
                return
            table = read_table(msg)
            view, joint_names = _RelationView(table), table.columns[1:]
        self.vkc.compute(view)
        values = np.column_stack([self.vkc.features, self.vkc.jacobian])
        rotation = 3 if self.vkc.rotation_names else None
        self.outputs['features'].write(table_msg(self.vkc.names, ('value', *joint_names), values,
                                                 rotation=rotation))
