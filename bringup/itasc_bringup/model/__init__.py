"""The iTaSC application model (paper §4.2): a YAML DSL for the levels Application,
Constraint-based program and Task, its validation and its transformation into the generic
composition model of the runtime.

Its names are imported on first use (:mod:`itasc_core.lazy`): building the schema takes a second or
more (every registered kind's section), which a command that only lists the applications
(``bootstrap --help``) must not pay."""

from __future__ import annotations

from typing import TYPE_CHECKING

from itasc_core.lazy import lazy_exports

if TYPE_CHECKING:
    from .load import load_application
    from .schema import Application
    from .transform import to_composition

__all__ = ['Application', 'load_application', 'to_composition']

__getattr__ = lazy_exports(__name__, {'Application': '.schema', 'load_application': '.load',
                                      'to_composition': '.transform'})
