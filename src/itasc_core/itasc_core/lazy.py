"""Names of a package imported on first use (PEP 562 module ``__getattr__``).

A process imports only what it uses: one that hosts only Tasks (``--deploy per-composite``) never
loads the Solvers' qpsolvers and scipy.sparse through ``itasc_core.itasc``'s re-exports.
"""

from __future__ import annotations

import importlib
import sys
from typing import Any, Callable

__all__ = ['lazy_exports']


def lazy_exports(package: str, modules: dict[str, str]) -> Callable[[str], Any]:
    """A module ``__getattr__`` for ``package`` that imports name ``n`` from its submodule
    ``modules[n]`` (relative, e.g. ``'.solver'``) when first asked for, and keeps it."""
    namespace = sys.modules[package].__dict__

    def __getattr__(name: str) -> Any:
        module = modules.get(name)
        if module is None:
            raise AttributeError(f'module {package!r} has no attribute {name!r}')
        value = namespace[name] = getattr(importlib.import_module(module, package), name)
        return value
    return __getattr__
