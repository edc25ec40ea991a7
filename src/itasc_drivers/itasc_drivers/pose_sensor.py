"""PoseSensor: a Sensor (paper §4.1 "Sensors", §4.2 "Application") delivering the measured pose of
a moving object from an existing ROS topic (``geometry_msgs/PoseStamped``, expressed in the
world frame) to the Scene: output ``pose`` with semantics ``Pose(<object>|world)@world``.
"""

from __future__ import annotations

from typing import Any

from geometry_msgs.msg import PoseStamped

from itasc_core.communication.ports import PortSpec
from itasc_core.computation.functional_entity import FunctionalEntity
from itasc_core.itasc.entities.scene_entity import object_pose

__all__ = ['PoseSensor']


class PoseSensor(FunctionalEntity):
    """The newest pose received on ``topic``, every tick."""

    PARAMETERS = {'object': 'object', 'topic': '/object_pose'}

    @classmethod
    def port_specs(cls, params: dict[str, Any]) -> list[PortSpec]:
        return [PortSpec(name='pose', direction='output', msg_type=PoseStamped, type='pose',
                         semantics=object_pose(params['object']))]

    def configure(self, params: dict[str, Any]) -> None:
        if getattr(self, '_subscription', None) is not None:
            self.destroy_subscription(self._subscription)
        self.latest: PoseStamped | None = None
        self._subscription = self.create_subscription(PoseStamped, params['topic'], self._on_pose, 10)

    def _on_pose(self, msg: PoseStamped) -> None:
        self.latest = msg

    def update(self, t: float) -> None:
        if self.latest is not None:
            self.outputs['pose'].write(self.latest)
