"""CDR bytes of a data-flow sample, without building its ROS message (issue #9: recording and
visualization off the control path; paper §6.1, the data flow observable on its topics).

A recording stores every message as the CDR bytes a DDS reader would have received. Building a
sample's ROS message and serialising it with rclpy costs tens of microseconds per message, too
much for every data-flow topic at 1 kHz. :func:`encoder` makes, once per message type, an encoder
that reads the fields from a sample (``t`` for ``stamp`` and ``header``; a sample class maps a
field its own way in ``MESSAGE_FIELDS``) or from a message, and writes them little-endian, XCDR1,
as Fast DDS writes them for ROS 2. Field types outside what the data flow uses give no encoder
(None): such a message is serialised by rclpy.

Where a field starts, and so the padding before it, depends on the lengths of the strings and
sequences before it; in a data flow these stay the same tick after tick (the names of a port do not
change, nor the sizes of its arrays). So an encoder keeps, per *shape* (the values of its strings and
name lists, the sizes of its number sequences), a template: one ``struct`` format
holding the padding and the encoded strings and counts, which the numbers of each message fill in a
single ``pack`` (1-3 us a message, against 4-12 us written field by field). A number sequence
that is already a numpy array of its type is packed as it is: ``numpy.asarray(x, 'd')`` alone cost
a third of a message's encoding. Padding bytes are
zeros (Fast CDR leaves them undefined): the bytes decode to the same message, they need not be
the same bytes.

The other way, :func:`sample_decoder` turns the CDR bytes a DDS reader takes (``raw=True``) into
the sample an input port hands its entity, without the ROS message rclpy would build first: a
process that reads another's data flow (``--deploy per-composite``) spends ~100 us of CPU on each
message it receives, and converting it through rclpy's message cost 75 us more, 40 us through a
decoder. Its arrays are views of one writable copy of the bytes, as rclpy's are copies.
"""

from __future__ import annotations

import importlib
import math
import struct
from dataclasses import dataclass
from typing import Any, Callable, Iterable

import numpy as np

__all__ = ['encoder', 'serialize', 'serialize_all', 'sample_decoder', 'received_as_sample']

Encode = Callable[[Any], bytes]

_HEADER = b'\x00\x01\x00\x00'  # CDR, little endian
_SCALARS = {'double': ('d', 8), 'float': ('f', 4), 'int32': ('i', 4), 'uint32': ('I', 4), 'int64': ('q', 8),
            'uint64': ('Q', 8), 'int16': ('h', 2), 'uint16': ('H', 2), 'int8': ('b', 1), 'uint8': ('B', 1),
            'octet': ('B', 1), 'boolean': ('?', 1)}
_U32 = struct.Struct('<I')
#: struct code -> numpy dtype (the singletons numpy's arrays of these types carry)
_DTYPES = {code: np.dtype(code) for code, _ in _SCALARS.values()}
#: The most templates an encoder keeps (a topic whose strings or sizes change every message would
#: otherwise grow them without end).
_TEMPLATES = 64


class Unsupported(ValueError):
    """A field type this encoder does not write."""


@dataclass(frozen=True)
class _Field:
    """One field: how to read it (an expression of ``obj``), its kind and, for numbers, their
    ``struct`` code and size."""

    kind: str  # scalar, string, strings, numbers, time, header
    read: str
    code: str = ''
    size: int = 0


def _fields(cls: type) -> list[_Field]:
    msg_type = getattr(cls, 'MESSAGE', cls)
    sample = msg_type is not cls
    special = getattr(cls, 'MESSAGE_FIELDS', {})
    fields = []
    for name, type_name in msg_type.get_fields_and_field_types().items():
        read = f'special[{name!r}](obj)' if name in special else f'obj.{name}'
        if type_name in _SCALARS:
            fields.append(_Field('scalar', read, *_SCALARS[type_name]))
        elif type_name == 'string':
            fields.append(_Field('string', read))
        elif type_name == 'sequence<string>':
            fields.append(_Field('strings', read))
        elif type_name.startswith('sequence<') and type_name[9:-1] in _SCALARS:
            fields.append(_Field('numbers', read, *_SCALARS[type_name[9:-1]]))
        elif type_name in ('builtin_interfaces/Time', 'std_msgs/Header'):
            kind = 'time' if type_name == 'builtin_interfaces/Time' else 'header'
            fields.append(_Field(kind, 'obj.t' if sample else read))
        else:
            raise Unsupported(f'{name}: {type_name}')
    return fields


def _string(value: str) -> bytes:
    data = value.encode()
    return _U32.pack(len(data) + 1) + data + b'\0'


def _strings(values) -> bytes:
    """A string sequence that starts 4-aligned: its count and strings with the padding between
    them (each string is 4-aligned), the same wherever in a message the sequence is."""
    out = bytearray(_U32.pack(len(values)))
    for value in values:
        out += b'\0' * (-len(out) % 4)
        out += _string(value)
    return bytes(out)


class _Layout:
    """Builds one shape's template: the ``struct`` format, with the constant parts in the order
    the encoder passes its arguments."""

    def __init__(self) -> None:
        self.format = ['<4s']
        self.constants: list[bytes] = [_HEADER]
        self.offset = 0  # from the end of the encapsulation header
        self.last = 0    # Fast CDR's "last data size": a value is aligned only when larger

    def align(self, size: int) -> None:
        if size > self.last and self.offset % size:
            pad = size - self.offset % size
            self.format.append(f'{pad}x')
            self.offset += pad

    def value(self, code: str, size: int) -> None:
        self.align(size)
        self.format.append(code)
        self.offset += size
        self.last = size

    def constant(self, data: bytes, *, last: int) -> None:
        self.align(4)  # a string, a string sequence or a count: each starts 4-aligned
        self.format.append(f'{len(data)}s')
        self.constants.append(data)
        self.offset += len(data)
        self.last = last

    def numbers(self, count: int, code: str, size: int) -> None:
        self.constant(_U32.pack(count), last=4)
        if count:  # Fast CDR writes nothing more for an empty sequence, not even the alignment
            self.align(size)
            self.last = size
        self.format.append(f'{count * size}s')
        self.offset += count * size


def _template(fields: list[_Field], values: list[Any]) -> tuple[Callable[..., bytes], tuple[bytes, ...]]:
    """One shape's pack function and constant parts; ``values``: one message's fields."""
    layout = _Layout()
    for field, value in zip(fields, values):
        if field.kind == 'scalar':
            layout.value(field.code, field.size)
        elif field.kind == 'string':
            layout.constant(_string(value), last=1)
        elif field.kind == 'strings':
            layout.constant(_strings(value), last=1 if len(value) else 4)
        elif field.kind == 'numbers':
            layout.numbers(value.size, field.code, field.size)
        else:  # time, header
            layout.value('i', 4)
            layout.value('I', 4)
            if field.kind == 'header':
                layout.constant(_string(getattr(value, 'frame_id', '')), last=1)  # a sample's: its time
    return struct.Struct(''.join(layout.format)).pack, tuple(layout.constants)


def _compile(cls: type) -> Encode | None:
    """The encoder of ``cls``: Python code written for its fields (a loop over field objects cost
    as much as the encoding it saves). Per message it reads each field once, finds its shape's
    template (made on first sight) and packs."""
    try:
        fields = _fields(cls)
    except Unsupported:
        return None
    sample = getattr(cls, 'MESSAGE', cls) is not cls
    lines, key, args = [], [], ['c[0]']  # c: the shape's constant parts, c[0] the header
    constants = 1
    for i, field in enumerate(fields):
        v = f'v{i}'
        lines.append(f'    {v} = {field.read}')
        if field.kind == 'numbers':  # a sample's arrays are already numpy arrays of the type, mostly
            lines.append(f'    if {v}.__class__ is not ndarray or {v}.dtype is not DTYPES[{field.code!r}]:')
            lines.append(f'        {v} = asarray({v}, {field.code!r})')
        if field.kind == 'scalar':
            args.append(v)
            continue
        if field.kind in ('time', 'header'):
            stamp = v if field.kind == 'time' else f'{v}.stamp'
            if sample:  # seconds -> (sec, nanosec), written out: a call per message costs more
                lines += [f'    sec{i} = floor({v})', f'    nsec{i} = round(({v} - sec{i}) * 1e9)',
                          f'    if nsec{i} > 999999999:', f'        nsec{i} = 999999999']
            args.append(f'sec{i}, nsec{i}' if sample else f'{stamp}.sec, {stamp}.nanosec')
            if field.kind == 'time':
                continue
            key.append("''" if sample else f'{v}.frame_id')
        elif field.kind == 'strings':
            # by value: a sample's names are often a new tuple each tick (a Solver's active tasks), and a
            # tuple of the same strings hashes in ~0.1 us (a string keeps its hash), a template takes ~30 us
            key.append(f'{v} if {v}.__class__ is tuple else tuple({v})')
        else:
            key.append(f'{v}.size' if field.kind == 'numbers' else v)
        args.append(f'c[{constants}]')  # the string, the name list, or the count of the numbers
        constants += 1
        if field.kind == 'numbers':
            args.append(f'{v}.tobytes()')
    values = ', '.join(f'v{i}' for i in range(len(fields)))
    source = '\n'.join([
        'def encode(obj):',
        *lines,
        f'    key = ({"".join(k + ", " for k in key)})',
        '    t = templates.get(key)',
        '    if t is None:',
        '        if len(templates) >= LIMIT:',
        '            templates.clear()',
        f'        t = templates[key] = template(fields, [{values}])',
        '    c = t[1]',
        f'    return t[0]({", ".join(args)})',
    ])
    scope: dict[str, Any] = {'asarray': np.asarray, 'ndarray': np.ndarray, 'DTYPES': _DTYPES, 'floor': math.floor,
                             'template': _template, 'fields': fields,
                             'special': getattr(cls, 'MESSAGE_FIELDS', {}), 'templates': {}, 'LIMIT': _TEMPLATES}
    exec(compile(source, f'<CDR encoder of {cls.__qualname__}>', 'exec'), scope)
    return scope['encode']


_ENCODERS: dict[type, Encode | None] = {}


def encoder(cls: type) -> Encode | None:
    """The CDR encoder of the objects of ``cls``: a ROS message class, or a sample class (of its
    ``MESSAGE``); None when a field's type is not one the encoder writes. Made once per class."""
    if cls not in _ENCODERS:
        _ENCODERS[cls] = _compile(cls)
    return _ENCODERS[cls]


def serialize(obj: Any) -> bytes:
    """The CDR bytes of a sample or a ROS message: by its compiled encoder, else by rclpy."""
    encode = encoder(type(obj))
    if encode is not None:
        return encode(obj)
    from rclpy.serialization import serialize_message

    from itasc_core.communication.samples import as_message
    return serialize_message(as_message(obj))


def serialize_all(samples: Iterable[Any]) -> list[bytes]:
    """The CDR bytes of each of ``samples`` (a tick's, tapped for a recording); a sample given more
    than once (a Driver's joint state, also on ``<robot>/joint_states``) is encoded once. The
    samples are all alive until this returns, so no ``id`` is reused among them."""
    encoded: dict[int, bytes] = {}
    out = []
    for sample in samples:
        data = encoded.get(id(sample))
        if data is None:
            data = encoded[id(sample)] = serialize(sample)
        out.append(data)
    return out


class _Fields:
    """A decoded message's fields, read by a sample class's ``from_message`` as a message's."""

    def __init__(self, **fields: Any) -> None:
        self.__dict__.update(fields)


def _decode_lines(field: _Field, target: str, index: int) -> list[str]:
    """Source that reads ``field`` at offset ``o`` of ``b`` into ``target`` (standard CDR alignment,
    from the end of the encapsulation header: what Fast CDR writes, see :class:`_Layout`). A name
    list is the same message after message on a data-flow topic: its bytes are compared with the
    last ones (``seen[index]``) and, when equal, its names taken from there (a list of 13 names
    took ~13 us to decode)."""
    def aligned(size: int) -> str:
        return f'o += -(o - 4) % {size}'

    def string(into: str) -> list[str]:
        return [aligned(4), 'n = U32(b, o)[0]', 'o += 4', f'{into} = b[o:o + n - 1].decode() if n else ""',
                'o += n']
    if field.kind == 'scalar':
        return [aligned(field.size), f'{target} = unpack_from("<{field.code}", b, o)[0]', f'o += {field.size}']
    if field.kind == 'string':
        return string(target)
    if field.kind == 'strings':
        parse = ['start = o', 'c = U32(b, o)[0]', 'o += 4', 'names = []', 'for _ in range(c):',
                 *('    ' + line for line in string('name')), '    names.append(name)',
                 f'{target} = tuple(names)', f'seen[{index}] = (bytes(b[start:o]), {target})']
        return [aligned(4), f'last = seen[{index}]',
                'if last is not None and b[o:o + len(last[0])] == last[0]:',
                f'    {target} = last[1]', '    o += len(last[0])',
                'else:', *('    ' + line for line in parse)]
    if field.kind == 'numbers':
        return [aligned(4), 'c = U32(b, o)[0]', 'o += 4', f'if c: {aligned(field.size)}',
                f'{target} = frombuffer(b, "<{field.code}", c, o)', f'o += c * {field.size}']
    lines = [aligned(4), 'sec, nanosec = unpack_from("<iI", b, o)', 'o += 8',
             'stamp = Fields(sec=sec, nanosec=nanosec)']
    if field.kind == 'time':
        return [*lines, f'{target} = stamp']
    return [*lines, *string('frame_id'), f'{target} = Fields(stamp=stamp, frame_id=frame_id)']


def _compile_decoder(cls: Any) -> Callable[[bytes], Any] | None:
    from rclpy.serialization import deserialize_message

    from itasc_core.communication.samples import as_sample
    message = cls.MESSAGE
    try:
        fields = _fields(message)
    except Unsupported:
        return None
    names = list(message.get_fields_and_field_types())
    body = ['b = bytearray(data)', 'o = 4']  # the encapsulation header, then the fields
    for index, (name, field) in enumerate(zip(names, fields)):
        body += _decode_lines(field, f'f_{name}', index)
    fields_args = ', '.join(f'{name}=f_{name}' for name in names)
    source = '\n'.join([
        'def decode(data):',
        '    if len(data) >= 4 and data[1] != 1:  # not little-endian plain CDR (XCDR1): rclpy reads it',
        '        return as_sample(deserialize_message(data, message))',
        '    try:',
        *('        ' + line for line in body),
        '    except (struct.error, ValueError, UnicodeDecodeError, IndexError) as err:',
        f'        raise ValueError(f"not the CDR of a {message.__name__}: {{err}}") from None',
        f'    return from_message(Fields({fields_args}))',
    ])
    scope: dict[str, Any] = {'U32': _U32.unpack_from, 'unpack_from': struct.unpack_from, 'frombuffer': np.frombuffer,
                             'Fields': _Fields, 'from_message': cls.from_message, 'struct': struct,
                             'seen': [None] * len(fields), 'message': message, 'as_sample': as_sample,
                             'deserialize_message': deserialize_message}
    exec(compile(source, f'<CDR decoder of {cls.__qualname__}>', 'exec'), scope)
    return scope['decode']


_DECODERS: dict[type, Callable[[bytes], Any] | None] = {}


def sample_decoder(msg_type: type) -> Callable[[bytes], Any] | None:
    """The function from the CDR bytes of a ``msg_type`` message to its sample (raises ValueError
    for bytes that are not one); None when ``msg_type`` has no sample class or a field of a type
    the decoder does not read. Made once per type."""
    if msg_type not in _DECODERS:
        from itasc_core.communication.samples import sample_class
        cls = sample_class(msg_type)
        _DECODERS[msg_type] = None if cls is None else _compile_decoder(cls)
    return _DECODERS[msg_type]


def received_as_sample(msg_type: type) -> tuple[Callable[[Any], Any], bool]:
    """How a subscription to ``msg_type`` gets its samples: the function from what it takes to the
    sample, and whether it takes the raw CDR bytes (:func:`sample_decoder`) or rclpy's message."""
    decode = sample_decoder(msg_type)
    if decode is not None:
        return decode, True
    from itasc_core.communication.samples import as_sample
    return as_sample, False


def message_class(type_name: str) -> type:
    """The rclpy class of ``pkg/msg/Type``."""
    package, kind, name = type_name.split('/')
    return getattr(importlib.import_module(f'{package}.{kind}'), name)
