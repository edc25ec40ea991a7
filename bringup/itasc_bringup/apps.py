"""Finding and loading the model of an application (paper §4.2; SPEC "The application model").

An application is named (``approach_object`` -> ``config/apps/approach_object.yaml`` in the
share directory of itasc_bringup, or the repository's ``config/`` when running from source) or
given by path. The file decides what it is: an iTaSC application model (top-level key
``application``) is validated, checked and transformed into the composition model; a model of the
Composition Pattern itself (top-level key ``composite``) is validated and checked (registered
entity kinds, existing ports that agree on their metadata). Either way, a wrong model is a
``ModelError`` before anything starts.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import yaml

from pydantic import ValidationError
from itasc_core.composition.checks import check_composite
from itasc_core.composition.loader import ModelError, load_yaml_tree, validate_tree
from itasc_core.composition.model import CompositeModel

from .model import to_composition
from .model.load import KEY, application_of
from .model.locations import config_dirs, include_roots, known_apps

__all__ = ['resolve_app', 'load_composition', 'write_composition', 'check_model', 'known_apps']


def resolve_app(app: str) -> Path:
    """The model file of application ``app`` (a name or a path)."""
    path = Path(app)
    if path.suffix in ('.yaml', '.yml') or len(path.parts) > 1:
        return path
    for directory in config_dirs():
        candidate = directory / 'apps' / f'{app}.yaml'
        if candidate.is_file():
            return candidate
    raise ModelError(app, '', f'no application named {app!r}; known: {known_apps()}')


def load_composition(app: str) -> CompositeModel:
    """The composition model of application ``app``; raises :class:`ModelError` if it is wrong.

    Nothing of the model is run: it is read within the bounds of ``itasc_core.composition.loader``,
    validated, checked, and (an iTaSC application) transformed."""
    path = resolve_app(app)
    try:
        data, sources = load_yaml_tree(path, roots=include_roots(path))
        if isinstance(data, dict) and KEY in data:
            app_model = application_of(data, sources, path=path)
            try:
                return to_composition(app_model)
            except ValidationError as err:  # a check is missing: still no traceback, and nothing started
                raise ModelError(str(path), '', f'cannot be composed: {err.errors()[0]["msg"]}') from None
        if isinstance(data, dict) and 'composite' in data:
            model = validate_tree(CompositeModel, data, sources, path=path, key='composite')
            check_composite(model, sources, at=('composite',))
            return model
    except (RecursionError, MemoryError, UnicodeError) as err:  # bounds missed: still no traceback
        raise ModelError(str(path), '', f'cannot be loaded: {type(err).__name__}') from None
    raise ModelError(str(path), '', "expected a top-level 'application' (iTaSC application model) or "
                     "'composite' (composition model)")


def write_composition(data: dict[str, Any], path: Path) -> Path:
    """Write a composition model (as ``CompositeModel.model_dump(by_alias=True)`` gives it) to the
    model file ``path`` (``composite:``); infinite values are written as ±1e300, since a model file
    holds finite numbers only."""
    def finite(value: Any) -> Any:
        if isinstance(value, float) and math.isinf(value):
            return math.copysign(1e300, value)
        if isinstance(value, list):
            return [finite(v) for v in value]
        if isinstance(value, dict):
            return {k: finite(v) for k, v in value.items()}
        return value
    path.write_text(yaml.safe_dump({'composite': finite(data)}, sort_keys=False))
    return path


def check_model(path: str | Path) -> ModelError | None:
    """Why the model of ``path`` (or application name) is wrong, or None if it loads and transforms."""
    try:
        load_composition(str(path))
    except ModelError as err:
        return err
    return None
