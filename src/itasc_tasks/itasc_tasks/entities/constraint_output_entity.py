"""ConstraintOutputEntity: the Constraint Output of a Task (paper §4.1 "CO", §4.2, Fig. 2).

Wraps :class:`itasc_tasks.constraint_output.ConstraintOutput`: y = f(chi_f, q) selects the
feature coordinates named in ``outputs`` (none: all) and the matching Jacobian rows. Input
``features`` (``Features(<task>)``), output ``output`` (``Output(<task>)``): y with its Jacobian
on the program-wide joint velocities, a labelled table that marks a complete rotation triple.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from itasc_core.communication.ports import PortSpec
from itasc_core.computation.functional_entity import FunctionalEntity
from itasc_core.itasc.entities.messages import read_table, table_msg

from ..constraint_output import ConstraintOutput
from .common import names, table_port

__all__ = ['ConstraintOutputEntity']

_ROTATION = ('rx', 'ry', 'rz')


class _FeatureView:
    """What a Constraint Output reads of a VKC, from a features table."""

    names: tuple[str, ...] = ()
    rotation_names: tuple[str, ...] = ()
    features = np.zeros(0)
    jacobian = np.zeros((0, 0))


class ConstraintOutputEntity(FunctionalEntity):
    """Selects the Task's outputs y among the feature coordinates."""

    PARAMETERS = {'task': 'task', 'outputs': ['']}

    @classmethod
    def port_specs(cls, params: dict[str, Any]) -> list[PortSpec]:
        return [table_port('features', 'input', 'Features', params['task']),
                table_port('output', 'output', 'Output', params['task'])]

    def configure(self, params: dict[str, Any]) -> None:
        self.co = ConstraintOutput(names(params['outputs']) or None)
        self._view = _FeatureView()

    def update(self, t: float) -> None:
        msg = self.inputs['features'].latest
        if msg is None:
            return
        table = read_table(msg)
        view = self._view
        view.names = table.rows  # the same tuple while the labels do not change: no re-binding
        view.rotation_names = _ROTATION if table.rotation is not None else ()
        view.features, view.jacobian = table.column('value'), table.matrix()
        self.co.compute(view)
        rotation = self.co.rotation.start if self.co.rotation is not None else None
        values = np.column_stack([self.co.y, self.co.jacobian])
        self.outputs['output'].write(table_msg(self.co.names, table.columns, values, rotation=rotation))
