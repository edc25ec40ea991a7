"""ROS interface types named in a model (paper §7.1: communication typed by metadata), for the
outside events a model maps to events of a composite: ``pkg/msg/Name`` or ``pkg/srv/Name``
(``pkg/Name`` as ``ros2 topic pub`` takes it), resolved to the generated Python class, and the
fields of such a type.

A model is data: only a name of that form is resolved, by importing the ``msg`` or ``srv`` module
of the interface package it names (the generated code ``ros2 topic echo`` imports too); what is
found must be a generated message or service. Every fault is an :class:`InterfaceError` whose
message says what exists instead; the model checks turn it into a model error naming file and path.
No rclpy import here: models are checked before anything starts.
"""

from __future__ import annotations

import importlib
import re
from typing import Any, Literal

__all__ = ['InterfaceError', 'interface', 'field_type', 'read', 'check_value', 'TYPE_PATTERN']

#: ``pkg/msg/Name``, ``pkg/srv/Name`` or ``pkg/Name``.
TYPE_PATTERN = r'^([A-Za-z][A-Za-z0-9_]*)/(?:(msg|srv)/)?([A-Z][A-Za-z0-9]*)$'
_WORD = {'msg': 'message', 'srv': 'service'}
_INTEGERS = re.compile(r'^(u?int(8|16|32|64)|byte|char|octet)$')
_FLOATS = ('float', 'double', 'long double')


class InterfaceError(ValueError):
    """An interface type or field a model names that does not exist, or a value that does not fit."""


def interface(name: str, kind: Literal['msg', 'srv']) -> type:
    """The generated class of message (``kind='msg'``) or service (``'srv'``) type ``name``."""
    match = re.match(TYPE_PATTERN, name)
    if match is None:
        raise InterfaceError(f"'{name}' is not a ROS {_WORD[kind]} type: expected <package>/{kind}/<Name>")
    package, given, class_name = match.groups()
    if given is not None and given != kind:
        raise InterfaceError(f"'{name}' is a {_WORD[given]} type; a {_WORD[kind]} type is expected here")
    try:
        module = importlib.import_module(f'{package}.{kind}')
    except ImportError:
        raise InterfaceError(f"unknown {_WORD[kind]} type '{name}': no installed package '{package}' has "
                             f'{_WORD[kind]}s') from None
    found = getattr(module, class_name, None)
    generated = hasattr(found, 'Request') and hasattr(found, 'Response') if kind == 'srv' \
        else hasattr(found, 'get_fields_and_field_types')
    if not isinstance(found, type) or not generated:
        known = sorted(n for n in dir(module) if n[:1].isupper() and not n.startswith('Metaclass'))
        raise InterfaceError(f"unknown {_WORD[kind]} type '{name}': {package} has no {_WORD[kind]} "
                             f"'{class_name}'; it has {known}")
    return found


def field_type(cls: type, path: str) -> str:
    """The ROS type (``boolean``, ``double``, ``string``, ...) of field ``path`` (``data``,
    ``header.frame_id``) of message class ``cls`` (a service's ``Request``)."""
    current: Any = cls
    ros_type = ''
    for k, part in enumerate(path.split('.')):
        if current is None:
            raise InterfaceError(f"field '{'.'.join(path.split('.')[:k])}' is a {ros_type}: it has no field "
                                 f"'{part}'")
        fields = current.get_fields_and_field_types()
        if part not in fields:
            raise InterfaceError(f"{_name(current)} has no field '{part}'; its fields: {sorted(fields)}")
        ros_type = fields[part]
        current = interface(ros_type, 'msg') if re.match(TYPE_PATTERN, ros_type) else None
    return ros_type


def check_value(ros_type: str, value: Any) -> None:
    """Refuse a value a field of ``ros_type`` can never equal (only booleans, numbers and strings
    are compared)."""
    if ros_type == 'boolean':
        ok = isinstance(value, bool)
    elif _INTEGERS.match(ros_type):
        ok = isinstance(value, int) and not isinstance(value, bool)
    elif ros_type in _FLOATS:
        ok = isinstance(value, (int, float)) and not isinstance(value, bool)
    elif re.match(r'^w?string(<=\d+)?$', ros_type):
        ok = isinstance(value, str)
    else:
        raise InterfaceError(f'the field is a {ros_type}: only a boolean, number or string field is compared '
                             'with a value')
    if not ok:
        raise InterfaceError(f'{value!r} is no {ros_type} value')


def read(msg: Any, path: str) -> Any:
    """The value of field ``path`` of ``msg``."""
    for part in path.split('.'):
        msg = getattr(msg, part)
    return msg


def _name(cls: type) -> str:
    module = cls.__module__.split('.')
    return f'{module[0]}/{module[1].lstrip("_")}/{cls.__name__}' if len(module) > 1 else cls.__name__
