"""PoseSensor: a Sensor (paper §4.1 "Sensors", §4.2 "Application") delivering the measured pose of
a moving object from an existing ROS topic (``geometry_msgs/PoseStamped``, expressed in the
world frame) to the Scene: output ``pose`` with semantics ``Pose(<object>|world)@world``.
"""

from __future__ import annotations

from geometry_msgs.msg import PoseStamped
from pydantic import Field
from rclpy.subscription import Subscription

from itasc_core.communication.ports import PortSpec
from itasc_core.communication.qos import OUTSIDE_QOS
from itasc_core.computation.functional_entity import FunctionalEntity
from itasc_core.computation.parameters import ParameterModel, TopicName
from itasc_core.itasc.entities.scene_entity import object_pose

__all__ = ['PoseSensor']


class PoseSensor(FunctionalEntity):
    """The newest pose received on ``topic``, every tick."""
    _subscription: Subscription | None = None

    class Parameters(ParameterModel):
        object: str = Field(default='object', frozen=True)
        """The object whose pose it measures."""
        topic: TopicName = '/object_pose'
        """Where ``geometry_msgs/PoseStamped`` poses (world frame) arrive."""

    @classmethod
    def port_specs(cls, params: Parameters) -> list[PortSpec]:
        return [PortSpec(name='pose', direction='output', msg_type=PoseStamped, type='pose',
                         semantics=object_pose(params.object))]

    def configure(self, params: Parameters) -> None:
        subscription = self.subscription_for(self._subscription, PoseStamped, params.topic, self._on_pose, OUTSIDE_QOS)
        self.let_go(self._subscription, kept=subscription)
        if subscription is not self._subscription:  # another topic: no pose from it yet
            self.latest: PoseStamped | None = None
        self._subscription = subscription

    def _on_pose(self, msg: PoseStamped) -> None:
        self.latest = msg

    def update(self, t: float) -> None:
        if self.latest is not None:
            self.outputs['pose'].write(self.latest)
