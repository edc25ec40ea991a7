"""What a Solver kind is (paper §4.1 "Solver": the prioritised problem of all Tasks' constraint rows
solved for joint velocities) and their registry (entry point group ``itasc.solvers``).

A Solver kind brings its settings (its parameter model: the program's ``solver`` section and the
Solver entity's ROS parameters), how it is made from them, and ``solve``. Adding one is a file with
its class and a line in ``setup.py``.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import ClassVar

import numpy as np

from ...computation.parameters import NoParameters, ParameterModel
from ...kinds import Registry
from .problem import ConstraintRows, SolverResult

__all__ = ['Solver', 'SOLVERS']


class Solver:
    """Joint velocities from prioritised constraint rows, within joint position and velocity limits."""

    #: The kind's own settings.
    Parameters: ClassVar[type[ParameterModel]] = NoParameters

    @classmethod
    def create(cls, params: ParameterModel, *, joint_weights: float | np.ndarray,
               position_limit_gain: float) -> Solver:
        """The Solver for ``params`` (a model with at least the kind's fields)."""
        raise NotImplementedError

    def solve(self, rows: Sequence[ConstraintRows], *, q: np.ndarray, lower: np.ndarray,
              upper: np.ndarray, velocity_limit: np.ndarray, dt: float) -> SolverResult:
        raise NotImplementedError


SOLVERS: Registry[Solver] = Registry('itasc.solvers', what='solver', base=Solver)
