"""Loading models from YAML files that reference each other, with errors that name the file, the
path inside it and what was expected (the paper's lesson: small files a newcomer can change with
confidence, §3.3).

Any mapping ``{include: other.yaml}`` is replaced by the content of that file (relative to the
including file); errors inside it are reported against that file.

A model is data, read within bounds (README "Faults and bad input / Bad models"): each file a
regular file of at most :data:`MAX_BYTES`, UTF-8, parsed by libyaml's safe loader where available;
no key twice in a mapping; nesting at most :data:`MAX_DEPTH` levels and at most :data:`MAX_VALUES`
values in all, includes resolved; every number finite; includes only inside the folder tree of the
model file and the folders the caller allows (``roots``).
"""

from __future__ import annotations

import math
import os
import stat
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TypeVar

import yaml
from pydantic import BaseModel, ValidationError

__all__ = ['ModelError', 'load_yaml_tree', 'validate', 'load_model', 'format_loc', 'source_of',
           'validate_tree', 'MAX_BYTES', 'MAX_DEPTH', 'MAX_VALUES']

M = TypeVar('M', bound=BaseModel)
Loc = tuple[Any, ...]

#: The largest model file read (the shipped ones are below 3 kB).
MAX_BYTES = 1 << 20
#: The deepest nesting of mappings and lists, in one file and in the whole model with its includes.
MAX_DEPTH = 64
#: The most values (mappings, lists, scalars) of a model with its includes resolved.
MAX_VALUES = 50_000

#: libyaml's parser where PyYAML was built with it (much faster), else PyYAML's own.
_SafeLoader = getattr(yaml, 'CSafeLoader', yaml.SafeLoader)


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


@dataclass
class _Tree:
    """One loading of a model: where each subtree came from, the files already parsed, the budget."""

    roots: tuple[Path, ...]
    sources: dict[Loc, Path]
    parsed: dict[Path, Any] = field(default_factory=dict)
    values: int = 0


def load_yaml_tree(path: str | Path, *, roots: tuple[Path, ...] = ()) -> tuple[Any, dict[Loc, Path]]:
    """Load ``path`` with its includes resolved; returns the data and where each subtree came from.

    Includes may reach files under the folder of ``path`` and under ``roots``."""
    root = Path(path)
    folders = dict.fromkeys((root.resolve().parent, *(Path(r).resolve() for r in roots)))  # each once, in order
    tree = _Tree(roots=tuple(folders), sources={(): root})
    data = _resolve(_read(root, tree), base=root, loc=(), tree=tree, stack=(root.resolve(),))
    return data, tree.sources


def _read(path: Path, tree: _Tree, *, including: tuple[Path, Loc] | None = None) -> Any:
    """The parsed content of one file, read within the bounds of the module docstring."""
    def refuse(message: str) -> ModelError:
        if including is not None:
            return ModelError(str(including[0]), format_loc(including[1]), f"included file '{path}' {message}")
        return ModelError(str(path), '', message)

    resolved = path.resolve()
    if resolved in tree.parsed:
        return tree.parsed[resolved]
    try:
        info = os.stat(resolved)
        if not stat.S_ISREG(info.st_mode):
            raise refuse('is not a regular file (a directory, device or pipe cannot be a model)')
        if info.st_size > MAX_BYTES:
            raise refuse(f'is larger than {MAX_BYTES} bytes ({info.st_size}): not a model')
        fd = os.open(resolved, os.O_RDONLY | os.O_NONBLOCK)
        with os.fdopen(fd, 'rb') as stream:
            raw = stream.read(MAX_BYTES + 1)
    except OSError as err:
        raise refuse(f'cannot be read: {err.strerror}') from None
    if len(raw) > MAX_BYTES:
        raise refuse(f'is larger than {MAX_BYTES} bytes: not a model')
    try:
        text = raw.decode('utf-8')
    except UnicodeDecodeError as err:
        line = raw[:err.start].count(b'\n')
        column = err.start - (raw.rfind(b'\n', 0, err.start) + 1)
        raise ModelError(str(path), f'line {line + 1}, column {column + 1}',
                         f'not UTF-8 text (byte 0x{raw[err.start]:02x}): a model is UTF-8 YAML') from None
    tree.parsed[resolved] = data = _parse(text, path, budget=MAX_VALUES - tree.values)
    return data


def _parse(text: str, path: Path, *, budget: int) -> Any:
    try:
        _scan(text, path, budget=budget)
        loader = _SafeLoader(text)
        try:
            return loader.get_single_data()
        finally:
            loader.dispose()
    except yaml.reader.ReaderError as err:  # a character YAML does not allow (control characters)
        line = text.count('\n', 0, err.position)
        column = err.position - (text.rfind('\n', 0, err.position) + 1)
        raise ModelError(str(path), f'line {line + 1}, column {column + 1}',
                         f'character U+{ord(err.character) if isinstance(err.character, str) else err.character:04X} '
                         'is not allowed in YAML (a control character)') from None
    except yaml.YAMLError as err:
        mark = getattr(err, 'problem_mark', None)
        where = f'line {mark.line + 1}, column {mark.column + 1}' if mark else ''
        problem = getattr(err, 'problem', None) or str(err)
        raise ModelError(str(path), where, f'YAML syntax error: {problem}') from None


def _scan(text: str, path: Path, *, budget: int) -> None:
    """Refuse nesting deeper than MAX_DEPTH, more than ``budget`` values and a key given twice in a
    mapping, from the parser's events, before anything is constructed (no recursion, no memory grows
    with the depth or the size)."""
    loader = _SafeLoader(text)
    stack: list[list[Any]] = []  # per open collection: [loc part, keys seen or None, next key or index]
    events = 0
    try:
        while not isinstance(event := loader.get_event(), yaml.StreamEndEvent):
            events += 1
            if events > 2 * budget:  # a value is one event (a scalar) or two (a collection), keys one
                loc = tuple(frame[0] for frame in stack[1:]) + ((stack[-1][2],) if stack else ())
                raise ModelError(str(path), format_loc(tuple(p for p in loc if p is not None)),
                                 f'the model has more than {MAX_VALUES} values '
                                 f'(line {event.start_mark.line + 1}): not a model')
            if isinstance(event, (yaml.MappingEndEvent, yaml.SequenceEndEvent)):
                stack.pop()
                _next(stack)
                continue
            if not isinstance(event, (yaml.ScalarEvent, yaml.AliasEvent, yaml.MappingStartEvent,
                                      yaml.SequenceStartEvent)):
                continue
            top = stack[-1] if stack else None
            if top is not None and top[1] is not None and top[2] is None:  # a mapping's key
                key = _key(loader, event)
                if key is not None and key in top[1] and key[1] != '<<':
                    where = [frame[0] for frame in stack[1:]] + [key[1]]
                    raise ModelError(str(path), format_loc(tuple(where)),
                                     f"key '{key[1]}' given twice in one mapping (line {top[1][key] + 1} and "
                                     f'line {event.start_mark.line + 1}): which one is meant?')
                if isinstance(event, (yaml.MappingStartEvent, yaml.SequenceStartEvent)):
                    raise ModelError(str(path), f'line {event.start_mark.line + 1}, column '
                                     f'{event.start_mark.column + 1}', 'a mapping key must be a plain value')
                if key is not None:
                    top[1][key] = event.start_mark.line
                top[2] = key[1] if key is not None else '?'
                continue
            if isinstance(event, (yaml.MappingStartEvent, yaml.SequenceStartEvent)):
                part = None if top is None else top[2]
                if len(stack) >= MAX_DEPTH:
                    loc = tuple(frame[0] for frame in stack[1:]) + (part,)
                    raise ModelError(str(path), format_loc(loc), f'nested deeper than {MAX_DEPTH} levels '
                                     f'(line {event.start_mark.line + 1}): not a model')
                mapping = isinstance(event, yaml.MappingStartEvent)
                stack.append([part, {} if mapping else None, None if mapping else 0])
                continue
            _next(stack)
    finally:
        loader.dispose()


def _key(loader: Any, event: Any) -> tuple[str, str] | None:
    if not isinstance(event, yaml.ScalarEvent):
        return None
    tag = event.tag
    if tag is None or tag == '!':
        tag = loader.resolve(yaml.ScalarNode, event.value, event.implicit)
    return tag, event.value


def _next(stack: list[list[Any]]) -> None:
    """A value of the innermost collection is complete."""
    if not stack:
        return
    top = stack[-1]
    top[2] = None if top[1] is not None else top[2] + 1


def _error_at(loc: Loc, tree: _Tree, message: str) -> ModelError:
    path, inner = source_of(loc, tree.sources)
    return ModelError(str(path), format_loc(inner), message)


def _resolve(value: Any, *, base: Path, loc: Loc, tree: _Tree, stack: tuple[Path, ...]) -> Any:
    tree.values += 1
    if tree.values > MAX_VALUES:
        raise _error_at(loc, tree, f'the model has more than {MAX_VALUES} values (includes resolved): not a model')
    if len(loc) > MAX_DEPTH:
        raise _error_at(loc, tree, f'nested deeper than {MAX_DEPTH} levels (includes resolved)')
    if isinstance(value, dict):
        if 'include' in value:
            if set(value) != {'include'} or not isinstance(value['include'], str):
                raise _error_at(loc + ('include',), tree, 'an include is {include: FILE} alone (a file name, no '
                                f'other field), got {value!r}')
            return _include(value['include'], base=base, loc=loc, tree=tree, stack=stack)
        return {k: _resolve(v, base=base, loc=loc + (k,), tree=tree, stack=stack) for k, v in value.items()}
    if isinstance(value, list):
        return [_resolve(v, base=base, loc=loc + (i,), tree=tree, stack=stack) for i, v in enumerate(value)]
    if isinstance(value, float) and not math.isfinite(value):
        raise _error_at(loc, tree, f'{value} is not a finite number')
    if isinstance(value, str) and _non_finite(value):  # a number field would read it as one
        raise _error_at(loc, tree, f'{value!r} is not a finite number')
    return value


def _non_finite(text: str) -> bool:
    """Whether ``text`` reads as a number that is not finite (``'inf'``, ``'nan'``, ``'1e400'``)."""
    try:
        return not math.isfinite(float(text))
    except ValueError:
        return False


def _include(reference: str, *, base: Path, loc: Loc, tree: _Tree, stack: tuple[Path, ...]) -> Any:
    at = source_of(loc, tree.sources)[1] + ('include',)
    target = Path(os.path.normpath(base.parent / reference))
    resolved = target.resolve()
    if resolved in stack:
        raise ModelError(str(base), format_loc(at), f"include cycle through '{reference}'")
    if not any(resolved.is_relative_to(root) for root in tree.roots):
        raise ModelError(str(base), format_loc(at), f"include '{reference}' ({resolved}) is outside the "
                         f"model's folder and the config folders: {[str(r) for r in tree.roots]}")
    content = _read(target, tree, including=(base, at))
    tree.sources[loc] = target
    return _resolve(content, base=target, loc=loc, tree=tree, stack=stack + (resolved,))


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
    # union tags: a composition entity's, a kind's (``condition=above``)
    loc = at + tuple(p for p in detail['loc']
                     if p not in ('entity', 'composite') and not (isinstance(p, str) and '=' in p))
    message = detail['msg'].removeprefix('Value error, ')
    if detail['type'] == 'unknown_kind':  # a kind field (``type``, ``condition``) naming no registered kind
        ctx = detail['ctx']
        if not isinstance(detail['input'], dict):  # ``solver: qp``: a section written as its kind alone
            message = f"expected a section ({{{ctx['field']}: ..., ...}}), got {detail['input']!r}"
        else:
            loc += (ctx['field'],)
            got = detail['input'].get(ctx['field'])
            message = 'required field is missing' if got is None else \
                f"unknown {ctx['what']} {got!r}; known: {ctx['known']}"
    given = detail.get('input')
    missing_at = detail['loc'][-1] if detail['type'] == 'missing' and isinstance(given, list) else None
    if isinstance(missing_at, int):  # a fixed-length list (xyz, rpy) of too few values: the list is wrong
        loc = loc[:-1]
    path, inner = source_of(loc, sources)
    if isinstance(missing_at, int) and isinstance(given, list):
        message = f'expected at least {missing_at + 1} values, got {len(given)} ({given})'
    elif detail['type'] == 'missing':
        message = 'required field is missing'
    elif detail['type'] == 'extra_forbidden':
        message = 'unknown field (not part of the model)'
    elif 'input' in detail and detail['type'] not in ('value_error', 'assertion_error', 'unknown_kind'):
        got = repr(detail['input'])
        message = f"{message} (got {got if len(got) <= 80 else got[:77] + '...'})"
    return ModelError(str(path), format_loc(inner), message)


def load_model(model: type[M], path: str | Path, *, key: str | None = None, roots: tuple[Path, ...] = ()) -> M:
    """Load and validate one model file (optionally the mapping under ``key``); includes may reach
    the folder of ``path`` and ``roots``."""
    data, sources = load_yaml_tree(path, roots=roots)
    return validate_tree(model, data, sources, path=path, key=key)


def validate_tree(model: type[M], data: Any, sources: dict[Loc, Path], *, path: str | Path,
                  key: str | None = None) -> M:
    """Validate a loaded tree (optionally the mapping under ``key``, the only top-level key)."""
    if key is None:
        return validate(model, data, sources)
    if not isinstance(data, dict) or key not in data:
        raise ModelError(str(path), key, 'required top-level field is missing')
    extra = sorted(map(str, set(data) - {key}))
    if extra:
        raise ModelError(str(path), extra[0], 'unknown top-level field (not part of the model)')
    return validate(model, data[key], sources, at=(key,))
