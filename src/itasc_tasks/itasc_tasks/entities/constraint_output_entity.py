"""ConstraintOutputEntity: the Constraint Output of a Task (paper §4.1 "CO", §4.2, Fig. 2).

Calls :class:`itasc_tasks.constraint_output.ConstraintOutput`: y = f(chi_f, q) selects the
feature coordinates named in ``outputs`` (none: all) and the matching Jacobian rows. Input
``features`` (``Features(<task>)``), output ``output`` (``Output(<task>)``): y with its Jacobian
on the program-wide joint velocities (``itasc_msgs/Features``), marking a complete rotation
triple, stamped as its features (the configuration they describe).
"""

from __future__ import annotations

from pydantic import Field

from itasc_core.communication.ports import PortSpec
from itasc_core.computation.functional_entity import FunctionalEntity
from itasc_core.computation.parameters import Names, ParameterModel
from itasc_core.itasc.entities.messages import FeaturesSample

from ..constraint_output import ConstraintOutput
from .common import TaskName, task_port

__all__ = ['ConstraintOutputEntity']


class ConstraintOutputEntity(FunctionalEntity):
    """Selects the Task's outputs y among the feature coordinates."""

    class Parameters(ParameterModel):
        task: TaskName = 'task'
        """The Task it belongs to."""
        outputs: Names = Field(default_factory=list, frozen=True)
        """The feature coordinates it selects (none: all)."""

    @classmethod
    def port_specs(cls, params: Parameters) -> list[PortSpec]:
        return [task_port('features', 'input', 'Features', params.task),
                task_port('output', 'output', 'Output', params.task)]

    def configure(self, params: Parameters) -> None:
        self.co = ConstraintOutput(list(params.outputs) or None)

    def update(self, t: float) -> None:
        features = self.inputs['features'].latest
        if features is None:
            return
        selection = self.co.bind(features.names, features.rotation)
        y, jacobian = selection(features.value, features.jacobian)
        self.outputs['output'].write(FeaturesSample(features.t, selection.names, features.joint_names, y, jacobian,
                                                    selection.rotation))
