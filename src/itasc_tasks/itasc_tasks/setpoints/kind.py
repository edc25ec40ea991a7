"""What a Setpoint Generator kind is (:mod:`itasc_tasks.setpoints`), their registry, and the fields
several kinds share (a target, per-output lists)."""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np
from itasc_core.computation.parameters import NoParameters, ParameterModel
from itasc_core.itasc.entities.scene_entity import Placement
from itasc_core.itasc.robot import se3
from itasc_core.kinds import Registry
from pydantic import model_validator

from ..setpoint_generator import SetpointGenerator, Value

__all__ = ['SetpointKind', 'SETPOINTS', 'Target', 'as_list', 'positive']


def as_list(value: Any) -> Any:
    """Accept a scalar where a list is expected (``value: 0.3``)."""
    return [value] if isinstance(value, (int, float)) and not isinstance(value, bool) else value


def positive(value: list[float] | None) -> list[float] | None:
    if value is not None and any(v <= 0 for v in value):
        raise ValueError('must be > 0')
    return value


class Target(ParameterModel):
    """A target: ``value`` in output space, or (a Cartesian Task) ``pose``, the pose of o2 in o1."""

    value: list[float] | None = None
    """The target in output space, one number per output [m, rad or the output's unit]."""
    pose: Placement | None = None
    """A Cartesian Task's target: the pose of o2 in o1."""

    @model_validator(mode='before')
    @classmethod
    def _listed(cls, data: Any) -> Any:
        if isinstance(data, dict) and 'value' in data:
            return {**data, 'value': as_list(data['value'])}
        return data

    @model_validator(mode='after')
    def _one(self) -> 'Target':
        if (self.value is None) == (self.pose is None):
            raise ValueError('give exactly one of value or pose')
        return self

    @property
    def target(self) -> Value:
        """The target as a generator takes it: a ``pin.SE3`` or a vector."""
        return se3(self.pose.xyz, self.pose.rpy) if self.pose is not None else np.array(self.value, dtype=float)


class SetpointKind:
    """A kind of Setpoint Generator: its fields and the generator it makes of them."""

    #: The kind's fields (after ``kind``).
    Parameters: ClassVar[type[ParameterModel]] = NoParameters

    @classmethod
    def generator(cls, params: Any) -> SetpointGenerator:
        """A new generator for ``params`` (a model with at least the kind's fields)."""
        raise NotImplementedError

    @classmethod
    def topic(cls, params: Any) -> str:
        """The topic of ``std_msgs/Float64MultiArray`` values its generator takes through ``push``
        ('' for none)."""
        return ''


SETPOINTS: Registry[SetpointKind] = Registry('itasc.setpoint_generators', what='setpoint generator',
                                             base=SetpointKind)
