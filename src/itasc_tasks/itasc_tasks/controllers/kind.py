"""What a Constraint Controller kind is (:mod:`itasc_tasks.controllers`) and their registry."""

from __future__ import annotations

import math
from typing import ClassVar

import numpy as np
from itasc_core.computation.parameters import ParameterModel
from itasc_core.kinds import Registry
from pydantic import Field

__all__ = ['ConstraintController', 'CONTROLLERS', 'Gains', 'limits', 'saturate']


class Gains(ParameterModel):
    """What every control law has: a proportional gain and a saturation."""

    kp: float = Field(default=1.0, ge=0, allow_inf_nan=False)
    """Proportional gain [1/s]: desired output velocity per unit of error (finite)."""
    max_output: float = Field(default=math.inf, gt=0)
    """Saturation of the desired output velocity [unit of the output per s]; ``.inf``: none."""


class ConstraintController:
    """A control law: the desired output velocity for an error and a feed-forward velocity. Its gains
    are plain attributes (scalars or vectors), so a Configurator switches them between named
    configurations (paper §5) while the law keeps its state."""

    #: The law's gains (its fields are a Task's ``controller`` section and the CC's ROS parameters).
    Parameters: ClassVar[type[ParameterModel]] = Gains
    kp: float | np.ndarray

    def configure(self, params: ParameterModel) -> None:
        """Take the gains of ``params`` (a model with at least the kind's fields)."""
        for key in type(self).Parameters.model_fields:
            setattr(self, key, getattr(params, key))

    def __call__(self, error: np.ndarray, feedforward: np.ndarray | float, dt: float) -> np.ndarray:
        raise NotImplementedError

    def reset(self) -> None:
        """Forget internal state (the Task was (re)activated)."""


CONTROLLERS: Registry[ConstraintController] = Registry('itasc.controllers', what='constraint controller',
                                                       base=ConstraintController)


def limits(bound: float | np.ndarray) -> bool:
    """Whether ``bound`` (a saturation, a bound of the integral) limits anything: an infinite
    float does not."""
    return not (isinstance(bound, float) and math.isinf(bound))


def saturate(out: np.ndarray, limit: float | np.ndarray) -> np.ndarray:
    """``out`` clipped to ``[-limit, limit]`` per component (an infinite float: no limit)."""
    if not limits(limit):
        return out
    return np.minimum(np.maximum(out, -np.asarray(limit)), limit)
