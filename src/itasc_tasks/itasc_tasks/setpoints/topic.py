"""The Setpoint Generator ``topic``: values in output space received on a ROS topic."""

from __future__ import annotations


from itasc_core.computation.parameters import ParameterModel, TopicName

from ..setpoint_generator import TopicSetpoint
from .kind import SetpointKind

__all__ = ['Topic']


class FromTopic(ParameterModel):
    topic: TopicName
    """Topic of ``std_msgs/Float64MultiArray`` setpoints, one value per output."""


class Topic(SetpointKind):
    """The values received on ``topic`` (``std_msgs/Float64MultiArray``, one per output); holds the
    current output until the first one arrives. A value that is not finite or not one per output
    puts the Task in Safety."""

    Parameters = FromTopic
    example = '{kind: topic, topic: /approach/setpoint}'

    @classmethod
    def generator(cls, params: FromTopic) -> TopicSetpoint:
        return TopicSetpoint()

    @classmethod
    def topic(cls, params: FromTopic) -> str:
        return params.topic
