"""Editing a copy of the shipped model files in tests (the ``config`` fixture of test/unit)."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Callable

import yaml

__all__ = ['edit_yaml']


def edit_yaml(file: Path, change: Callable[[Any], None]) -> None:
    """Rewrite the YAML ``file`` with ``change(data)`` applied to it."""
    data = yaml.safe_load(file.read_text())
    change(data)
    file.write_text(yaml.safe_dump(data, sort_keys=False))
