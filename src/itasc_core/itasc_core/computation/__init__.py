"""Computation (paper §4): the Functional Entity base, Monitors and a small library of entities."""

from .functional_entity import FunctionalEntity
from .conditions import CONDITIONS, Condition
from .monitor import Monitor

__all__ = ['FunctionalEntity', 'Monitor', 'Condition', 'CONDITIONS']
