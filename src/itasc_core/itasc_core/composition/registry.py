"""Entity kinds by name: what a model's ``kind`` field refers to (paper §4.3: a template per
kind of Functional Entity, and implementations attached to the model by metadata).

A kind is either a short name registered here or ``package.module:ClassName``.
"""

from __future__ import annotations

import importlib

from ..computation.functional_entity import FunctionalEntity

__all__ = ['resolve_kind', 'KINDS', 'UnknownKind']

KINDS: dict[str, str] = {
    'SineSource': 'itasc_core.computation.library:SineSource',
    'PController': 'itasc_core.computation.library:PController',
    'Integrator': 'itasc_core.computation.library:Integrator',
    'Sum': 'itasc_core.computation.library:Sum',
}


class UnknownKind(LookupError):
    pass


def resolve_kind(kind: str) -> type[FunctionalEntity]:
    """The Functional Entity class for ``kind``."""
    target = KINDS.get(kind, kind)
    module_name, _, class_name = target.partition(':')
    if not class_name:
        raise UnknownKind(f"unknown entity kind '{kind}': not one of {sorted(KINDS)} "
                          "and not of the form 'package.module:ClassName'")
    try:
        cls = getattr(importlib.import_module(module_name), class_name)
    except (ImportError, AttributeError) as err:
        raise UnknownKind(f"entity kind '{kind}' cannot be loaded: {err}") from None
    if not (isinstance(cls, type) and issubclass(cls, FunctionalEntity)):
        raise UnknownKind(f"entity kind '{kind}' is not a FunctionalEntity")
    return cls
