"""CDR bytes of a data-flow sample, without building its ROS message (issue #9: recording off the
control path).

A recording stores every message as the CDR bytes a DDS reader would have received. Building a
sample's ROS message and serialising it with rclpy costs tens of microseconds per message, too
much for every data-flow topic at 1 kHz; :func:`encoder` compiles, once per message type, the
field-by-field CDR encoding (little-endian, XCDR1 as Fast DDS writes it for ROS 2) from the
type's field list, reading the fields from a sample (``t`` for ``stamp`` and ``header``; a sample
class maps a field its own way in ``MESSAGE_FIELDS``) or from a message. Name lists are encoded
once and reused while they are the same object (a sample's names are). Field types outside what
the data flow uses give no encoder (None): such a message is serialised by rclpy. Padding bytes
are zeros (Fast CDR leaves them undefined): the bytes decode to the same message, they need not be
the same bytes.
"""

from __future__ import annotations

import importlib
import math
import operator
import struct
from typing import Any, Callable

import numpy as np

__all__ = ['encoder', 'serialize']

Encode = Callable[[Any], bytes]
#: ``op(out, obj, last) -> last``: writes one field; ``last`` is Fast CDR's "last data size", which
#: decides whether the next value is aligned (only when it is larger than the last one written)
_Op = Callable[[bytearray, Any, int], int]

_HEADER = b'\x00\x01\x00\x00'  # CDR, little endian
_SCALARS = {'double': ('<d', 8), 'float': ('<f', 4), 'int32': ('<i', 4), 'uint32': ('<I', 4), 'int64': ('<q', 8),
            'uint64': ('<Q', 8), 'int16': ('<h', 2), 'uint16': ('<H', 2), 'int8': ('<b', 1), 'uint8': ('<B', 1),
            'octet': ('<B', 1), 'boolean': ('<?', 1)}
_U32 = struct.Struct('<I')
_TIME = struct.Struct('<iI')


class Unsupported(ValueError):
    """A field type this encoder does not write."""


def _align(out: bytearray, size: int, last: int) -> None:
    if size > last:
        pad = -(len(out) - 4) % size
        if pad:
            out += b'\0' * pad


def _string(out: bytearray, value: str, last: int) -> int:
    data = value.encode()
    _align(out, 4, last)
    out += _U32.pack(len(data) + 1)
    out += data
    out += b'\0'
    return 1


def _strings(values, last: int) -> tuple[bytes, int]:
    """A string sequence written after ``last`` at a 4-aligned offset, and the last data size."""
    out = bytearray(_HEADER)  # offsets as in a message: only their remainder modulo 4 matters
    _align(out, 4, last)
    out += _U32.pack(len(values))
    last = 4
    for value in values:
        last = _string(out, value, last)
    return bytes(out[4:]), last


def _seconds(t: float) -> bytes:
    sec = math.floor(t)
    return _TIME.pack(sec, min(int(round((t - sec) * 1e9)), 999_999_999))


def _field(name: str, type_name: str, get: Callable[[Any], Any]) -> _Op:
    if type_name in _SCALARS:
        fmt, size = _SCALARS[type_name]
        pack = struct.Struct(fmt).pack

        def scalar(out: bytearray, obj: Any, last: int) -> int:
            _align(out, size, last)
            out += pack(get(obj))
            return size
        return scalar
    if type_name == 'string':
        def string(out: bytearray, obj: Any, last: int) -> int:
            return _string(out, get(obj), last)
        return string
    if type_name == 'sequence<string>':
        cache: dict[tuple[int, int], tuple[Any, bytes, int]] = {}

        def strings(out: bytearray, obj: Any, last: int) -> int:
            values = get(obj)
            _align(out, 4, last)  # the sequence starts 4-aligned: its encoding depends on nothing else
            hit = cache.get((id(values), last))
            if hit is None or hit[0] is not values:
                if len(cache) > 64:
                    cache.clear()
                hit = cache[id(values), last] = (values, *_strings(values, 4))
            out += hit[1]
            return hit[2]
        return strings
    if type_name.startswith('sequence<') and type_name[9:-1] in _SCALARS:
        fmt, size = _SCALARS[type_name[9:-1]]
        dtype = np.dtype(fmt)

        def sequence(out: bytearray, obj: Any, last: int) -> int:
            values = np.asarray(get(obj), dtype=dtype)
            _align(out, 4, last)
            out += _U32.pack(values.size)
            if not values.size:  # Fast CDR writes nothing more, not even the alignment
                return 4
            _align(out, size, 4)
            out += values.tobytes()
            return size
        return sequence
    if type_name == 'builtin_interfaces/Time':
        def time(out: bytearray, obj: Any, last: int) -> int:
            _align(out, 4, last)
            value = getattr(obj, name, None)
            out += _seconds(obj.t) if value is None else _TIME.pack(value.sec, value.nanosec)
            return 4
        return time
    if type_name == 'std_msgs/Header':
        def header(out: bytearray, obj: Any, last: int) -> int:
            _align(out, 4, last)
            value = getattr(obj, name, None)
            if value is None:  # a sample: its time, no frame
                out += _seconds(obj.t)
                return _string(out, '', 4)
            out += _TIME.pack(value.stamp.sec, value.stamp.nanosec)
            return _string(out, value.frame_id, 4)
        return header
    raise Unsupported(f'{name}: {type_name}')


_ENCODERS: dict[type, Encode | None] = {}


def encoder(cls: type) -> Encode | None:
    """The CDR encoder of the objects of ``cls``: a ROS message class, or a sample class (of its
    ``MESSAGE``); None when a field's type is not one the encoder writes. Made once per class."""
    if cls not in _ENCODERS:
        _ENCODERS[cls] = _compile(cls)
    return _ENCODERS[cls]


def _compile(cls: type) -> Encode | None:
    msg_type = getattr(cls, 'MESSAGE', cls)
    special = getattr(cls, 'MESSAGE_FIELDS', {})
    try:
        ops = [_field(name, type_name, special.get(name) or operator.attrgetter(name))
               for name, type_name in msg_type.get_fields_and_field_types().items()]
    except Unsupported:
        return None

    def encode(obj: Any) -> bytes:
        out = bytearray(_HEADER)
        last = 0
        for op in ops:
            last = op(out, obj, last)
        return bytes(out)
    return encode


def serialize(obj: Any) -> bytes:
    """The CDR bytes of a sample or a ROS message: by its compiled encoder, else by rclpy."""
    encode = encoder(type(obj))
    if encode is not None:
        return encode(obj)
    from rclpy.serialization import serialize_message

    from itasc_core.communication.samples import as_message
    return serialize_message(as_message(obj))


def message_class(type_name: str) -> type:
    """The rclpy class of ``pkg/msg/Type``."""
    package, kind, name = type_name.split('/')
    return getattr(importlib.import_module(f'{package}.{kind}'), name)
