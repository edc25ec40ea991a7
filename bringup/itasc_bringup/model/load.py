"""Loading an iTaSC application model: YAML with ``{include: file}`` references, schema validation
(pydantic) and cross-reference checks, every error a ``ModelError(file, path, message)``."""

from __future__ import annotations

from pathlib import Path

from itasc_core.composition.loader import ModelError, load_yaml_tree, validate

from .checks import check
from .schema import Application

__all__ = ['load_application', 'KEY']

#: The top-level key of an iTaSC application model file.
KEY = 'application'


def load_application(path: str | Path) -> Application:
    """The validated, checked application of the model file ``path`` (URDF paths resolved)."""
    data, sources = load_yaml_tree(path)
    if not isinstance(data, dict) or KEY not in data:
        raise ModelError(str(path), KEY, 'required top-level field is missing')
    extra = sorted(set(data) - {KEY})
    if extra:
        raise ModelError(str(path), str(extra[0]), 'unknown top-level field (not part of the model)')
    app = validate(Application, data[KEY], sources, at=(KEY,))
    return check(app, sources, root=(KEY,))
