"""Finding and loading the model of an application (paper §4.2; SPEC "The application model").

An application is named (``approach_object`` -> ``config/apps/approach_object.yaml`` in the
share directory of itasc_bringup, or the repository's ``config/`` when running from source) or
given by path. The file decides what it is: an iTaSC application model (top-level key
``application``) is validated, checked and transformed into the composition model; a model of the
Composition Pattern itself (top-level key ``composite``) is loaded as it is.
"""

from __future__ import annotations

from pathlib import Path

import yaml
from pydantic import ValidationError
from itasc_core.composition.loader import ModelError, load_model
from itasc_core.composition.model import CompositeModel

from .model import load_application, to_composition
from .model.locations import config_dirs

__all__ = ['resolve_app', 'load_composition', 'check_model', 'known_apps']


def known_apps() -> list[str]:
    return sorted({p.stem for d in config_dirs() for p in (d / 'apps').glob('*.yaml')})


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


def _kind(path: Path) -> str:
    try:
        with path.open() as stream:
            for event in yaml.parse(stream):  # the first key of the top-level mapping is enough
                if isinstance(event, yaml.ScalarEvent):
                    return event.value
    except OSError as err:
        raise ModelError(str(path), '', f'cannot be read: {err.strerror}') from None
    except yaml.YAMLError:
        return 'application'  # the loader reports the syntax error with its position
    return ''


def load_composition(app: str) -> CompositeModel:
    """The composition model of application ``app``; raises :class:`ModelError` if it is wrong."""
    path = resolve_app(app)
    kind = _kind(path)
    if kind == 'application':
        app_model = load_application(path)
        try:
            return to_composition(app_model)
        except ValidationError as err:  # a check is missing: still no traceback, and nothing started
            raise ModelError(str(path), '', f'cannot be composed: {err.errors()[0]["msg"]}') from None
    if kind == 'composite':
        return load_model(CompositeModel, path, key='composite')
    raise ModelError(str(path), '', "expected a top-level 'application' (iTaSC application model) or "
                     "'composite' (composition model)")


def check_model(path: str | Path) -> ModelError | None:
    """Why the model of ``path`` (or application name) is wrong, or None if it loads and transforms."""
    try:
        load_composition(str(path))
    except ModelError as err:
        return err
    return None
