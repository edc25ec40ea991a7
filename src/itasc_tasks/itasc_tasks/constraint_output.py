"""Constraint Output (paper §4.1 "CO"): the output equation y = f(chi_f, q) of a Task.

Selects feature coordinates of a VKC by name (``['x', 'y', 'z']``, ``['rz']``, ``['distance']``,
joint names), optionally combined linearly (``y = C chi_sel``), and gives the matching rows of
the Jacobian: ``ydot = jacobian @ qdot``.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Protocol

import numpy as np

__all__ = ['ConstraintOutput', 'FeatureSource', 'compact_index']


def compact_index(index: Sequence[int]) -> slice | np.ndarray:
    """A slice for consecutive ascending indices (cheap views), else an index array."""
    if len(index) and list(index) == list(range(index[0], index[0] + len(index))):
        return slice(index[0], index[0] + len(index))
    return np.array(index, dtype=int)


class FeatureSource(Protocol):
    """What a CO reads from a VKC."""

    names: tuple[str, ...]
    rotation_names: tuple[str, ...]
    features: np.ndarray
    jacobian: np.ndarray


class ConstraintOutput:
    """y = C chi_f[outputs] (C = identity unless ``combination`` is given)."""

    def __init__(self, outputs: Sequence[str] | None = None, *,
                 combination: np.ndarray | None = None) -> None:
        """``outputs``: feature names to select (None: all, in the VKC's order).
        ``combination``: optional (k, len(outputs)) matrix C combining the selected features."""
        self.outputs = None if outputs is None else tuple(outputs)
        self.combination = None if combination is None else np.atleast_2d(
            np.asarray(combination, dtype=float))
        self.names: tuple[str, ...] = ()
        self.rotation: slice | None = None  # where a complete (rx, ry, rz) triple sits in y
        self.y = np.zeros(0)
        self.jacobian = np.zeros((0, 0))
        self._bound: tuple[str, ...] | None = None
        self._index: slice | np.ndarray = slice(0)

    def _bind(self, vkc: FeatureSource) -> None:
        selected = vkc.names if self.outputs is None else self.outputs
        missing = [n for n in selected if n not in vkc.names]
        if missing:
            raise KeyError(f'constraint output {missing} not among the VKC features {vkc.names}')
        self._index = compact_index([vkc.names.index(n) for n in selected])
        self.rotation = None
        if self.combination is not None:
            if self.combination.shape[1] != len(selected):
                raise ValueError(f'combination has {self.combination.shape[1]} columns, '
                                 f'{len(selected)} outputs selected')
            self.names = tuple(f'y{i}' for i in range(self.combination.shape[0]))
        else:
            self.names = tuple(selected)
            rot = vkc.rotation_names
            if rot and all(r in selected for r in rot):
                start = selected.index(rot[0])
                if tuple(selected[start:start + 3]) != tuple(rot):
                    raise ValueError(f'select {rot} consecutively and in this order')
                self.rotation = slice(start, start + 3)
        self._bound = vkc.names

    def select(self, features: np.ndarray) -> np.ndarray:
        """Output values for a full feature vector (e.g. a feature-space setpoint)."""
        y = features[self._index]
        return y if self.combination is None else self.combination @ y

    def compute(self, vkc: FeatureSource) -> None:
        if self._bound is not vkc.names:
            self._bind(vkc)
        self.y = self.select(vkc.features)
        J = vkc.jacobian[self._index]
        self.jacobian = J if self.combination is None else self.combination @ J
