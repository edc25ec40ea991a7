"""What a Monitor condition kind is (:mod:`itasc_core.computation.conditions`) and their registry."""

from __future__ import annotations

from collections.abc import Sequence
from typing import ClassVar

from ...kinds import Registry
from ..parameters import NoParameters, ParameterModel

__all__ = ['Condition', 'CONDITIONS']


class Condition:
    """A condition on the values a Monitor watches, with its parameters."""

    #: The condition's parameters (its fields are the Monitor's, in the model and as ROS parameters).
    Parameters: ClassVar[type[ParameterModel]] = NoParameters
    #: False for a condition on the arrival of data only (``stale``): it is given no values.
    reads_values: ClassVar[bool] = True

    def __init__(self, params: ParameterModel) -> None:
        self.params = params

    def holds(self, values: Sequence[float] | None, *, age: float, seen: bool = True) -> bool:
        """Whether the condition holds for the newest ``values`` (None: none yet), which are
        ``age`` seconds old; ``seen``: whether any sample arrived since the Monitor started."""
        raise NotImplementedError


CONDITIONS: Registry[Condition] = Registry('itasc.conditions', what='monitor condition', base=Condition)
