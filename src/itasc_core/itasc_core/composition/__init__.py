"""Composition (paper §3): the composition model, the Composer and its run-time re-composition,
deployment and the entity registry."""

from .composer import Composer, bring_up
from .deployment import Runtime, make_executor
from .loader import ModelError, load_model
from .model import CompositeModel, EntityModel
from .registry import resolve_kind

__all__ = ['Composer', 'bring_up', 'Runtime', 'make_executor', 'ModelError', 'load_model', 'CompositeModel',
           'EntityModel', 'resolve_kind']
