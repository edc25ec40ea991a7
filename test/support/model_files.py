"""Editing a copy of the shipped model files in tests (the ``config`` fixture of test/unit), or a
shipped application written out with other Driver fields."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Callable

import yaml

__all__ = ['edit_yaml', 'app_with_drivers']

CONFIG = Path(__file__).resolve().parents[2] / 'config'


def edit_yaml(file: Path, change: Callable[[Any], None]) -> None:
    """Rewrite the YAML ``file`` with ``change(data)`` applied to it."""
    data = yaml.safe_load(file.read_text())
    change(data)
    file.write_text(yaml.safe_dump(data, sort_keys=False))


def app_with_drivers(app: str, directory: Path, **fields: Any) -> Path:
    """The shipped application ``app`` written to ``directory`` with ``fields`` set on each of its
    Drivers (e.g. ``silent_after=1.0``); its includes still name the shipped files."""
    data = yaml.safe_load((CONFIG / 'apps' / f'{app}.yaml').read_text())
    application = data['application']
    if isinstance(application.get('program'), dict) and 'include' in application['program']:
        application['program']['include'] = str(CONFIG / 'apps' / application['program']['include'])
    for driver in application['drivers']:
        driver.update(fields)
    path = directory / f'{app}.yaml'
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path
