"""Constraint Output (paper §4.1 "CO"): the output equation y = f(chi_f, q) of a Task.

Selects feature coordinates of a VKC by name (``['x', 'y', 'z']``, ``['rz']``, ``['distance']``,
joint names), optionally combined linearly (``y = C chi_sel``), and gives the matching rows of
the Jacobian: ``ydot = J_y qdot``. :meth:`ConstraintOutput.bind` resolves the names against a
chain's features once (a :class:`Selection`); the selection is then a function on arrays, the same
for the CO entity, the Setpoint Generator entity and :class:`~itasc_tasks.task.TaskComputation`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

__all__ = ['ConstraintOutput', 'Selection', 'compact_index']


def compact_index(index: Sequence[int]) -> slice | np.ndarray:
    """A slice for consecutive ascending indices (cheap views), else an index array."""
    if len(index) and list(index) == list(range(index[0], index[0] + len(index))):
        return slice(index[0], index[0] + len(index))
    return np.array(index, dtype=int)


@dataclass(frozen=True, eq=False)
class Selection:
    """A Constraint Output bound to a chain's features: y = C chi_f[index]."""

    names: tuple[str, ...]
    """One per output."""
    rotation: int | None
    """First row of a complete ``(rx, ry, rz)`` triple in y, or None."""
    index: slice | np.ndarray
    combination: np.ndarray | None

    def select(self, features: np.ndarray) -> np.ndarray:
        """Output values of a full feature vector (chi_f, a feature-space setpoint or its velocity)."""
        y = features[self.index]
        return y if self.combination is None else self.combination.dot(y)

    def __call__(self, features: np.ndarray, jacobian: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(y, J_y)`` of the chain's ``(chi_f, J_f)``."""
        index, C = self.index, self.combination
        if C is None:
            return features[index], jacobian[index]
        return C.dot(features[index]), C.dot(jacobian[index])


class ConstraintOutput:
    """y = C chi_f[outputs] (C = identity unless ``combination`` is given)."""

    def __init__(self, outputs: Sequence[str] | None = None, *,
                 combination: np.ndarray | Sequence[Sequence[float]] | None = None) -> None:
        """``outputs``: feature names to select (None: all, in the VKC's order).
        ``combination``: optional (k, len(outputs)) matrix C combining the selected features."""
        self.outputs = None if outputs is None else tuple(outputs)
        self.combination = None if combination is None else np.atleast_2d(np.asarray(combination, dtype=float))
        self._selection: Selection | None = None
        self._features: tuple[str, ...] = ()
        self._rotation: int | None = None

    def bind(self, feature_names: tuple[str, ...], rotation: int | None) -> Selection:
        """The selection among the chain's feature names ``feature_names`` (with a rotation triple at row
        ``rotation``), kept while they are the same."""
        if (feature_names is self._features or feature_names == self._features) and rotation == self._rotation \
                and self._selection is not None:
            return self._selection
        selected = feature_names if self.outputs is None else self.outputs
        missing = [n for n in selected if n not in feature_names]
        if missing:
            raise KeyError(f'constraint output {missing} not among the VKC features {feature_names}')
        index = compact_index([feature_names.index(n) for n in selected])
        output_rotation = None
        if self.combination is not None:
            if self.combination.shape[1] != len(selected):
                raise ValueError(f'combination has {self.combination.shape[1]} columns, '
                                 f'{len(selected)} outputs selected')
            names = tuple(f'y{i}' for i in range(self.combination.shape[0]))
        else:
            names = tuple(selected)
            triple = feature_names[rotation:rotation + 3] if rotation is not None else ()
            if triple and all(r in selected for r in triple):
                start = selected.index(triple[0])
                if tuple(selected[start:start + 3]) != triple:
                    raise ValueError(f'select {triple} consecutively and in this order')
                output_rotation = start
        self._selection = Selection(names, output_rotation, index, self.combination)
        self._features, self._rotation = feature_names, rotation
        return self._selection
