"""Complete message definitions for the schemas of an MCAP ROS 2 bag (SPEC: "recording the whole
run to MCAP"; paper §6.1: recordings show every Coordinator's state).

A reader without a ROS install (rosbags, Foxglove) decodes a message only from the *complete*
definition of its type: the type's own ``.msg`` text, then, for every nested type, recursively,
a delimiter line of 80 ``=`` and a ``MSG: pkg/Type`` line followed by that type's text. This is
the ``ros2msg`` schema encoding that rosbag2 writes (rosbag2_cpp ``LocalMessageDefinitionSource``,
docs/message_definition_encoding.md), reproduced here byte for byte: dependencies in sorted order,
each type once, depth first. A type with no ``.msg`` (IDL-only) falls back to ``ros2idl``.

The ``.msg``/``.idl`` files are read from ``<share of pkg>/msg/`` through ament_index_python; the
ROS 2 wheels and our colcon-built ``itasc_msgs`` install them there.
"""

from __future__ import annotations

import functools
import os
import re

__all__ = ['DefinitionNotFound', 'SEPARATOR', 'full_definition']

SEPARATOR = '=' * 80 + '\n'

_PRIMITIVES = frozenset({
    'bool', 'byte', 'char', 'float32', 'float64', 'int8', 'uint8', 'int16', 'uint16',
    'int32', 'uint32', 'int64', 'uint64', 'string', 'wstring',
})
_TYPE_NAME = re.compile(r'^([A-Za-z0-9_]+)/(?:msg/)?([A-Za-z0-9_]+)$')
_IDL_INCLUDE = re.compile(r'(?:^|\n)#include\s+(?:"|<)([A-Za-z0-9_/]+)\.idl(?:"|>)')


class DefinitionNotFound(LookupError):
    """No .msg (or .idl) file for a type in its package's share directory."""


@functools.lru_cache(maxsize=None)
def _read(type_name: str, ext: str) -> str:
    from ament_index_python.packages import PackageNotFoundError, get_package_share_directory

    match = _TYPE_NAME.match(type_name)
    if not match:
        raise DefinitionNotFound(f"'{type_name}' is not a message type name (pkg/msg/Type)")
    package, name = match.groups()
    try:
        share = get_package_share_directory(package)
    except (PackageNotFoundError, LookupError, OSError) as err:
        raise DefinitionNotFound(f"package '{package}' not found: {err}") from None
    path = os.path.join(share, 'msg', name + ext)
    try:
        with open(path, encoding='utf-8') as f:
            return f.read()
    except OSError:
        raise DefinitionNotFound(f'{path} does not exist') from None


def _msg_dependencies(text: str, package: str) -> list[str]:
    """Field types of a .msg that are messages, as written (``pkg/Type``), sorted, unique."""
    deps = set()
    for line in text.splitlines():
        line = line.split('#', 1)[0].strip()
        if not line:
            continue
        field_type = re.split(r'[\s\[<]', line, maxsplit=1)[0]
        if field_type in _PRIMITIVES or not field_type:
            continue
        deps.add(field_type if '/' in field_type else f'{package}/{field_type}')
    return sorted(deps)


def _idl_dependencies(text: str) -> list[str]:
    return sorted(set(_IDL_INCLUDE.findall(text)))


def _delimiter(kind: str, type_name: str) -> str:
    return f'{SEPARATOR}{kind}: {type_name}\n'


def _append(type_name: str, ext: str, seen: set[str]) -> str:
    text = _read(type_name, ext)
    if ext == '.msg':
        deps = _msg_dependencies(text, type_name.split('/', 1)[0])
    else:
        deps = _idl_dependencies(text)
    kind = 'MSG' if ext == '.msg' else 'IDL'
    result = text
    for dep in deps:
        if dep not in seen:
            seen.add(dep)
            result += '\n' + _delimiter(kind, dep) + _append(dep, ext, seen)
    return result


@functools.lru_cache(maxsize=None)
def full_definition(type_name: str) -> tuple[str, str]:
    """``(schema_encoding, text)`` of the complete definition of ``pkg/msg/Type``.

    ``ros2msg`` when the .msg files exist, else ``ros2idl``. Raises DefinitionNotFound.
    """
    try:
        return 'ros2msg', _append(type_name, '.msg', set())
    except DefinitionNotFound:
        pass
    return 'ros2idl', _delimiter('IDL', type_name) + _append(type_name, '.idl', set())
