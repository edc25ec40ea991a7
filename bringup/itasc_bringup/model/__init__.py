"""The iTaSC application model (paper §4.2): a YAML DSL for the levels Application,
Constraint-based program and Task, its validation and its transformation into the generic
composition model of the runtime."""

from .load import load_application
from .schema import Application
from .transform import to_composition

__all__ = ['Application', 'load_application', 'to_composition']
