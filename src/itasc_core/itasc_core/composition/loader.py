"""Loading models from YAML files that reference each other, with errors that name the file, the
path inside it and what was expected (the paper's lesson: small files a newcomer can change with
confidence, §3.3).

Any mapping ``{include: other.yaml}`` is replaced by the content of that file (relative to the
including file); errors inside it are reported against that file.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeVar

import yaml
from pydantic import BaseModel, ValidationError

__all__ = ['ModelError', 'load_yaml_tree', 'validate', 'load_model', 'format_loc']

M = TypeVar('M', bound=BaseModel)
Loc = tuple[Any, ...]


@dataclass
class ModelError(Exception):
    """A wrong model: which file, where in it, and what was expected."""

    file: str
    path: str
    message: str

    def __str__(self) -> str:
        where = f'{self.file}: {self.path}' if self.path else self.file
        return f'{where}: {self.message}'


def format_loc(loc: Loc) -> str:
    """``('tasks', 1, 'controller', 'kp')`` -> ``tasks[1].controller.kp``."""
    text = ''
    for part in loc:
        if isinstance(part, int):
            text += f'[{part}]'
        else:
            text += f'.{part}' if text else str(part)
    return text


def load_yaml_tree(path: str | Path) -> tuple[Any, dict[Loc, Path]]:
    """Load ``path`` with its includes resolved; returns the data and where each subtree came from."""
    root = Path(path)
    sources: dict[Loc, Path] = {(): root}
    data = _resolve(_read(root, stack=()), base=root, loc=(), sources=sources, stack=(root.resolve(),))
    return data, sources


def _read(path: Path, *, stack: tuple[Path, ...], including: tuple[Path, Loc] | None = None) -> Any:
    try:
        text = path.read_text()
    except OSError as err:
        if including is not None:
            raise ModelError(str(including[0]), format_loc(including[1]),
                             f"included file '{path}' cannot be read: {err.strerror}") from None
        raise ModelError(str(path), '', f'cannot be read: {err.strerror}') from None
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError as err:
        mark = getattr(err, 'problem_mark', None)
        where = f'line {mark.line + 1}, column {mark.column + 1}' if mark else ''
        problem = getattr(err, 'problem', None) or str(err)
        raise ModelError(str(path), where, f'YAML syntax error: {problem}') from None


def _resolve(value: Any, *, base: Path, loc: Loc, sources: dict[Loc, Path], stack: tuple[Path, ...]) -> Any:
    if isinstance(value, dict):
        if set(value) == {'include'} and isinstance(value['include'], str):
            target = (base.parent / value['include'])
            if target.resolve() in stack:
                raise ModelError(str(base), format_loc(loc), f"include cycle through '{value['include']}'")
            sources[loc] = target
            content = _read(target, stack=stack, including=(base, loc + ('include',)))
            return _resolve(content, base=target, loc=loc, sources=sources, stack=stack + (target.resolve(),))
        return {k: _resolve(v, base=base, loc=loc + (k,), sources=sources, stack=stack) for k, v in value.items()}
    if isinstance(value, list):
        return [_resolve(v, base=base, loc=loc + (i,), sources=sources, stack=stack) for i, v in enumerate(value)]
    return value


def source_of(loc: Loc, sources: dict[Loc, Path]) -> tuple[Path, Loc]:
    """The file a location lies in, and the location relative to that file."""
    best: Loc = ()
    for prefix in sources:
        if len(prefix) > len(best) and loc[: len(prefix)] == prefix:
            best = prefix
    return sources[best], loc[len(best):]


def validate(model: type[M], data: Any, sources: dict[Loc, Path], *, at: Loc = ()) -> M:
    """Validate ``data`` (found at ``at`` in the tree) against ``model``; the first error becomes a
    :class:`ModelError`."""
    try:
        return model.model_validate(data)
    except ValidationError as err:
        raise _first_error(err, sources, at) from None


def _first_error(err: ValidationError, sources: dict[Loc, Path], at: Loc) -> ModelError:
    detail = err.errors()[0]
    loc = at + tuple(p for p in detail['loc'] if p not in ('entity', 'composite'))  # union tags
    path, inner = source_of(loc, sources)
    message = detail['msg'].removeprefix('Value error, ')
    if detail['type'] == 'missing':
        message = 'required field is missing'
    elif detail['type'] == 'extra_forbidden':
        message = 'unknown field (not part of the model)'
    elif 'input' in detail and detail['type'] not in ('value_error', 'assertion_error'):
        message = f"{message} (got {detail['input']!r})"
    return ModelError(str(path), format_loc(inner), message)


def load_model(model: type[M], path: str | Path, *, key: str | None = None) -> M:
    """Load and validate one model file (optionally the mapping under ``key``)."""
    data, sources = load_yaml_tree(path)
    if key is None:
        return validate(model, data, sources)
    if not isinstance(data, dict) or key not in data:
        raise ModelError(str(path), key, 'required top-level field is missing')
    return validate(model, data[key], sources, at=(key,))
