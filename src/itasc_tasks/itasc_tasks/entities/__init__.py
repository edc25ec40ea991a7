"""ROS 2 Functional Entities of a Task composite (paper §4.2 "Task", Fig. 2): VKC, Constraint
Output, Setpoint Generator, Constraint Controller, and the entity that delivers the Task's
constraint rows to the Solver. They wrap the plain-Python math of :mod:`itasc_tasks`."""

from .constraint_controller_entity import ConstraintControllerEntity
from .constraint_output_entity import ConstraintOutputEntity
from .constraint_rows_entity import ConstraintRowsEntity
from .setpoint_generator_entity import SetpointGeneratorEntity
from .vkc_entity import VKCEntity

__all__ = ['VKCEntity', 'ConstraintOutputEntity', 'SetpointGeneratorEntity', 'ConstraintControllerEntity',
           'ConstraintRowsEntity']
