"""Typed parameters of a Functional Entity (paper §5: what a Configurator sets; §4.3: a kind's
template): one pydantic model per entity kind is the single source of

* the entity's validation (at construction, and for every change: a Configurator's or a
  ``ros2 param set``, see :meth:`~.functional_entity.FunctionalEntity.ros_parameters`),
* the DSL schema wherever the model is part of the application model (a controller's gains, a
  Monitor's condition, a chain's frames, ...),
* the ROS 2 parameter declarations: each field is one parameter with its type, its docstring as
  description, its bounds as ``FloatingPointRange``/``IntegerRange`` and its other constraints as
  ``additional_constraints``, a frozen field as read-only (what ``ros2 param describe`` shows).

ROS parameters hold no nested structures: a nested model ``m`` is declared as ``m.<field>``, a
``dict[str, Model]`` ``d`` as ``d.<key>.<field>`` (YAML parameter files nest them the same way). A
field that is None is not declared (ROS parameters have no None).
"""

from __future__ import annotations

import array
import math
import types
import typing
from collections.abc import Mapping
from typing import Annotated, Any, Literal

from pydantic import AfterValidator, BaseModel, ConfigDict, Field, ValidationError, ValidationInfo, field_validator
from pydantic.fields import FieldInfo
from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
from rclpy.parameter import Parameter

from ..documented import Documented
from ..kinds import derived_model

__all__ = ['FileModel', 'ParameterModel', 'NoParameters', 'Names', 'TopicName', 'declarations', 'flatten', 'nest',
           'ros_type', 'problems', 'partial', 'no_bool_for_number']

_INT64 = 2 ** 63 - 1


class FileModel(BaseModel, metaclass=Documented):
    """Base of every model read from a file (the application and composition models, the
    entities' parameters): unknown fields refused, ``true``/``false`` no number
    (:func:`no_bool_for_number`), field docstrings kept as descriptions."""

    model_config = ConfigDict(extra='forbid')

    @field_validator('*', mode='before')
    @classmethod
    def _no_bool(cls, value: Any, info: ValidationInfo) -> Any:
        return no_bool_for_number(cls, value, info)


class ParameterModel(FileModel):
    """Base of every entity's parameter model: a :class:`FileModel` with no NaN anywhere (rclpy's
    ranges let a NaN through where a parameter has none: a threshold, a list)."""

    @field_validator('*')
    @classmethod
    def _no_nan(cls, value: Any) -> Any:
        if _has_nan(value):
            raise ValueError(f'NaN is not a value (got {value})')
        return value


def no_bool_for_number(cls: type[BaseModel], value: Any, info: ValidationInfo) -> Any:
    """A ``field_validator('*', mode='before')``: ``true``/``false`` where a number is expected is
    refused (pydantic's lax mode reads them as 1 and 0: ``rate: true`` ran at 1 Hz). For every
    model read from a file: the entities' parameters, the application and the composition models."""
    field = cls.model_fields.get(info.field_name) if info.field_name else None
    if field is None or _admits_bool(field.annotation):
        return value
    numbers = _numbers_of(field.annotation)
    if isinstance(value, bool) and numbers:
        raise ValueError(f'expected a number, got {str(value).lower()}')
    if isinstance(value, (list, tuple)) and any(isinstance(v, bool) for v in value) and numbers:
        raise ValueError(f"expected numbers, got [{', '.join(str(v).lower() for v in value)}]")
    return value


def _admits_bool(annotation: Any) -> bool:
    if annotation is bool or annotation is Any:
        return True
    return any(_admits_bool(arg) for arg in typing.get_args(annotation))


def _numbers_of(annotation: Any) -> bool:
    """Whether ``annotation`` is (or holds) ``int`` or ``float``."""
    if annotation in (int, float):
        return True
    return any(_numbers_of(arg) for arg in typing.get_args(annotation))


def _has_nan(value: Any) -> bool:
    if isinstance(value, float):
        return math.isnan(value)
    if isinstance(value, (list, tuple)):
        return any(_has_nan(v) for v in value)
    if isinstance(value, dict):
        return any(_has_nan(v) for v in value.values())
    return False  # a nested model checked its own fields


class NoParameters(ParameterModel):
    """An entity without parameters."""


def _distinct(names: list[str]) -> list[str]:
    twice = sorted({name for name in names if names.count(name) > 1})
    if twice:
        raise ValueError(f'{", ".join(map(repr, twice))} given more than once')
    return names


#: Names each given once: a Task's outputs or a joint chain's joints, where a name twice would be a
#: constraint row twice.
Names = Annotated[list[str], AfterValidator(_distinct)]


def _topic_name(name: str) -> str:
    from rclpy.exceptions import InvalidTopicNameException
    from rclpy.expand_topic_name import expand_topic_name
    from rclpy.validate_full_topic_name import validate_full_topic_name
    from rclpy.validate_topic_name import validate_topic_name
    try:
        validate_topic_name(name)
        validate_full_topic_name(expand_topic_name(name, 'node', '/'))
    except InvalidTopicNameException as err:
        why = str(err).splitlines()[0].removeprefix('Invalid topic name: ').rstrip(':')
        raise ValueError(f'{name!r} is not a ROS topic name: {why}') from None
    return name


#: A ROS topic name (absolute, relative or private), as rclpy checks it when a node subscribes or
#: publishes: a wrong one is refused with the model, not by the node that would have used it.
TopicName = Annotated[str, AfterValidator(_topic_name), Field(json_schema_extra={  # for editors; rclpy decides
    'pattern': r'^(~/|/)?[A-Za-z_{][A-Za-z0-9_{}]*(/[A-Za-z_{][A-Za-z0-9_{}]*)*$'})]


def flatten(values: BaseModel) -> dict[str, Any]:
    """``values`` as ROS parameter values by dotted name (None fields left out)."""
    return {name: value for name, value, _ in _leaves(values)}


def _leaves(values: BaseModel, prefix: str = '') -> list[tuple[str, Any, FieldInfo]]:
    """Every declared parameter of ``values``: dotted name, ROS value and the field it comes from."""
    leaves: list[tuple[str, Any, FieldInfo]] = []
    for name, info in type(values).model_fields.items():
        value = getattr(values, name)
        key = f'{prefix}{name}'
        if value is None:
            continue
        if isinstance(value, BaseModel):
            leaves += _leaves(value, f'{key}.')
        elif isinstance(value, Mapping):
            item = FieldInfo(annotation=_unwrap(typing.get_args(_unwrap(info.annotation))[1]),
                             description=info.description, frozen=info.frozen)
            for k, v in value.items():
                leaves += _leaves(v, f'{key}.{k}.') if isinstance(v, BaseModel) else [(f'{key}.{k}', _plain(v), item)]
        else:
            leaves.append((key, _plain(value), info))
    return leaves


def nest(flat: Mapping[str, Any]) -> dict[str, Any]:
    """Dotted ROS parameter names back into the nested mapping a model validates."""
    nested: dict[str, Any] = {}
    for name, value in flat.items():
        *path, last = name.split('.')
        node = nested
        for part in path:
            node = node.setdefault(part, {})
        node[last] = list(value) if isinstance(value, (array.array, tuple)) else value
    return nested


def declarations(values: BaseModel) -> list[tuple[str, Any, ParameterDescriptor]]:
    """What to declare for ``values``: per leaf, ``(name, value, descriptor)``."""
    return [(name, value, describe(info, value)) for name, value, info in _leaves(values)]


def problems(err: Exception) -> str:
    """A validation error in one line: ``field.path: what is wrong; ...``."""
    if not isinstance(err, ValidationError):
        return str(err)
    return '; '.join(f"{'.'.join(map(str, e['loc'])) or 'parameters'}: {e['msg']}" for e in err.errors())


def partial(*models: type[BaseModel], name: str, doc: str, exclude: tuple[str, ...] = ()) -> type[BaseModel]:
    """The fields of ``models`` but ``exclude``, each optional (default None), constraints and
    docstrings kept: what a named configuration may change of them."""
    fields: dict[str, Any] = {}
    for model in models:
        for key, info in model.model_fields.items():
            if key not in exclude:
                fields[key] = (typing.Optional[info.annotation], FieldInfo.merge_field_infos(info, default=None))
    return derived_model(name, base=ParameterModel, doc=doc, **fields)


def ros_type(value: Any, info: FieldInfo | None = None) -> Parameter.Type:
    """The ROS parameter type of ``value`` (an empty list takes its element type from ``info``)."""
    if isinstance(value, list) and not value and info is not None:
        return _LIST_TYPES.get(_element(info.annotation), Parameter.Type.STRING_ARRAY)
    return Parameter.Type.from_parameter_value(value)


def describe(info: FieldInfo | None, value: Any) -> ParameterDescriptor:
    """The descriptor of a parameter of field ``info`` holding ``value``."""
    descriptor = ParameterDescriptor(type=ros_type(value, info).value)
    if info is None:
        return descriptor
    descriptor.description = ' '.join((info.description or '').split())
    descriptor.read_only = bool(info.frozen)
    low, high, notes = _bounds(info)
    choices = _choices(info.annotation)
    if choices and not descriptor.read_only:
        notes.append('one of ' + ', '.join(choices))
    if isinstance(value, bool) or not (low > -math.inf or high < math.inf):
        pass
    elif isinstance(value, int):
        descriptor.integer_range = [IntegerRange(from_value=int(max(low, -_INT64)), to_value=int(min(high, _INT64)),
                                                 step=0)]
    elif isinstance(value, float):
        descriptor.floating_point_range = [FloatingPointRange(from_value=float(low), to_value=float(high), step=0.0)]
    descriptor.additional_constraints = '; '.join(notes)
    return descriptor


# -- model structure --------------------------------------------------------------------------------

_LIST_TYPES = {float: Parameter.Type.DOUBLE_ARRAY, int: Parameter.Type.INTEGER_ARRAY,
               bool: Parameter.Type.BOOL_ARRAY, str: Parameter.Type.STRING_ARRAY}


def _plain(value: Any) -> Any:
    return list(value) if isinstance(value, tuple) else value


def _unwrap(annotation: Any) -> Any:
    """``X | None`` and ``Annotated[X, ...]`` -> X."""
    while True:
        origin = typing.get_origin(annotation)
        if origin is typing.Annotated:
            annotation = typing.get_args(annotation)[0]
        elif origin in (typing.Union, types.UnionType):
            args = [a for a in typing.get_args(annotation) if a is not type(None)]
            if len(args) != 1:
                return annotation
            annotation = args[0]
        else:
            return annotation


def _element(annotation: Any) -> Any:
    args = typing.get_args(_unwrap(annotation))
    return _unwrap(args[0]) if args else str


def _choices(annotation: Any) -> list[str]:
    inner = _unwrap(annotation)
    if typing.get_origin(inner) is Literal:
        return [str(a) for a in typing.get_args(inner)]
    return []


#: annotated_types' bounds and how a message says them.
_LIMITS = {'ge': '>=', 'gt': '>', 'le': '<=', 'lt': '<'}


def _bounds(info: FieldInfo) -> tuple[float, float, list[str]]:
    """Lowest and highest value a scalar field allows, and its constraints in words."""
    low, high, notes = -math.inf, math.inf, []
    for item in info.metadata:  # annotated_types' Ge, Gt, Le, Lt and MinLen, as pydantic keeps them
        for attribute, words in _LIMITS.items():
            value = getattr(item, attribute, None)
            if value is not None:
                if attribute in ('ge', 'gt'):
                    low = max(low, float(value))
                else:
                    high = min(high, float(value))
                notes.append(f'{words} {value}')
                break
        else:
            if getattr(item, 'min_length', None):
                notes.append('not empty' if item.min_length == 1 else f'at least {item.min_length} values')
    return low, high, notes
