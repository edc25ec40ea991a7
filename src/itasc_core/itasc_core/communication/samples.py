"""Samples: what a data-flow port hands to the ports of its own process (paper §4.3, §7).

An entity writes a *sample*: the fields of its port's ROS message, numbers as numpy arrays, names
as tuples, the stamp as seconds (``t``). A co-located input gets the sample object itself, so
nothing is converted, copied or parsed between entities of one process; the port builds the ROS
message only when a DDS reader wants it (another process, ``ros2 topic echo``), and an input fed
over DDS turns each message's CDR bytes into the sample its entity reads
(:func:`~itasc_core.communication.cdr.sample_decoder`, no ROS message built). A sample is never changed after it
was written (every reader may hold it).

A sample class is registered for its message type (:func:`sample_of`); a port whose message type
has none carries the messages themselves (e.g. ``std_msgs/Float64``).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any, ClassVar

import numpy as np
from builtin_interfaces.msg import Time
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64

__all__ = ['Sample', 'sample_of', 'sample_class', 'as_sample', 'as_message', 'stamp', 'seconds', 'floats',
           'JointSample', 'Float64Sample']

_SAMPLES: dict[type, type['Sample']] = {}


#: The default of an absent field: an empty array, never written to.
_EMPTY = np.zeros(0)

class Sample:
    """Base of the samples: the in-process form of one ROS message type."""

    __slots__ = ()
    #: The ROS message class this sample stands for.
    MESSAGE: ClassVar[type]
    #: Message fields a sample holds in a form of its own: field name -> its value from a sample
    #: (a serialiser that writes messages from samples uses them).
    MESSAGE_FIELDS: ClassVar[dict[str, Callable[[Any], Any]]] = {}

    def to_message(self) -> Any:
        raise NotImplementedError

    @classmethod
    def from_message(cls, msg: Any) -> 'Sample':
        raise NotImplementedError


def sample_of(message: type):
    """Class decorator: the decorated :class:`Sample` stands for ROS messages of type ``message``."""
    def register(cls: type[Sample]) -> type[Sample]:
        cls.MESSAGE = message
        _SAMPLES[message] = cls
        return cls
    return register


def sample_class(message: type) -> type['Sample'] | None:
    """The sample class of ROS messages of type ``message`` (None: its messages are their own samples)."""
    return _SAMPLES.get(message)


def as_sample(msg: Any) -> Any:
    """The sample of a ROS message (the message itself if its type has no sample class)."""
    cls = _SAMPLES.get(type(msg))
    return msg if cls is None else cls.from_message(msg)


def as_message(sample: Any) -> Any:
    """The ROS message of a sample (a message is returned as it is)."""
    return sample.to_message() if isinstance(sample, Sample) else sample


def stamp(t: float) -> Time:
    """Seconds ``t`` (program time, or time since the epoch) as a ROS time stamp."""
    sec = math.floor(t)
    return Time(sec=sec, nanosec=min(int(round((t - sec) * 1e9)), 999_999_999))


def seconds(time: Time) -> float:
    return time.sec + time.nanosec * 1e-9


def floats(values: Sequence[float]) -> np.ndarray:
    """A message's float64 sequence as a numpy array (no copy of an ``array.array``)."""
    return np.asarray(values, dtype=float)


@sample_of(JointState)
class JointSample(Sample):
    """``sensor_msgs/JointState``: joint ``name``\\ s with their ``position``, ``velocity`` and
    ``effort`` (each empty or one per name) at ``t``."""

    __slots__ = ('t', 'name', 'position', 'velocity', 'effort')

    def __init__(self, t: float, name: tuple[str, ...], position: np.ndarray = _EMPTY, *,
                 velocity: np.ndarray = _EMPTY, effort: np.ndarray = _EMPTY) -> None:
        self.t, self.name, self.position, self.velocity, self.effort = t, name, position, velocity, effort

    def to_message(self) -> JointState:
        msg = JointState(name=list(self.name), position=self.position.tolist(), velocity=self.velocity.tolist(),
                         effort=self.effort.tolist())
        msg.header.stamp = stamp(self.t)
        return msg

    @classmethod
    def from_message(cls, msg: JointState) -> 'JointSample':
        return cls(seconds(msg.header.stamp), tuple(msg.name), floats(msg.position), velocity=floats(msg.velocity),
                   effort=floats(msg.effort))


@sample_of(Float64)
class Float64Sample(Sample):
    """``std_msgs/Float64``: one number, ``data``."""

    __slots__ = ('data',)

    def __init__(self, data: float) -> None:
        self.data = data

    def to_message(self) -> Float64:
        return Float64(data=self.data)

    @classmethod
    def from_message(cls, msg: Float64) -> 'Float64Sample':
        return cls(msg.data)
