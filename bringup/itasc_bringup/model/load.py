"""Loading an iTaSC application model: YAML with ``{include: file}`` references, schema validation
(pydantic) and cross-reference checks, every error a ``ModelError(file, path, message)``."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from itasc_core.composition.loader import load_yaml_tree, validate_tree

from .checks import check
from .locations import include_roots
from .schema import Application

__all__ = ['load_application', 'application_of', 'KEY']

#: The top-level key of an iTaSC application model file.
KEY = 'application'


def load_application(path: str | Path) -> Application:
    """The validated, checked application of the model file ``path`` (URDF paths resolved)."""
    data, sources = load_yaml_tree(path, roots=include_roots(path))
    return application_of(data, sources, path=path)


def application_of(data: Any, sources: dict, *, path: str | Path) -> Application:
    """The validated, checked application of a loaded model tree (see ``load_yaml_tree``)."""
    app = validate_tree(Application, data, sources, path=path, key=KEY)
    return check(app, sources, root=(KEY,))
