"""The registry of kinds (paper §4.3: a template per kind, the implementation attached by metadata):
task types, monitor conditions, ... each registered once, under a name a model refers to.

A kind is a class that brings everything the project needs of it: its typed parameter model
(:mod:`.computation.parameters`: the same model is its section of the application model and its
entity's ROS parameters), its computation, and what the model transform does with it. Kinds are
registered through Python entry points, one group per category (``itasc.task_types``,
``itasc.conditions``, ``itasc.controllers``, ``itasc.setpoint_generators``, ``itasc.solvers``,
``itasc.drivers``), the way launch_ros and colcon find their extensions: this project's own
kinds in its packages' ``setup.py``, kinds of other packages in theirs. Adding a kind is one new
file and one registration line. Nothing is imported before a model names the category. A kind
may give an ``example`` (its section in YAML), which ``docs/model.md`` shows where no shipped
model uses the kind.
"""

from __future__ import annotations

import functools
import os
import sys
from collections.abc import Mapping
from importlib.metadata import EntryPoint, EntryPoints, entry_points
from typing import Annotated, Any, Generic, Literal, TypeVar, Union, cast

from pydantic import BaseModel, Discriminator, Field, Tag, ValidationError, create_model, model_validator

__all__ = ['Registry', 'UnknownKind', 'UnloadableKind', 'variants', 'with_kind', 'derived_model', 'TAG', 'PROJECT']

K = TypeVar('K')
M = TypeVar('M', bound=BaseModel)
#: The distributions of this project (its own kinds; any other is a plugin's).
PROJECT = ('itasc_core', 'itasc_tasks', 'itasc_drivers', 'itasc_bringup')
#: How a kind's variant is tagged in a union (``condition=above``): the loader leaves such tags out of
#: the paths its errors name.
TAG = '{field}={name}'


#: The broken kinds said on stderr (``<group>:<name>``, space-separated), by this process or the one
#: that started it: an application's processes (the display, the composite processes) load the same
#: kinds, and the user is told once.
TOLD = 'ITASC_BROKEN_KINDS_TOLD'


class UnknownKind(ValueError, LookupError):
    pass


class UnloadableKind(UnknownKind):
    """A registered kind that cannot be used: its module does not import, its entry point names
    nothing of the right base class, or its parameter model's defaults break its own rules."""


@functools.cache
def _installed() -> EntryPoints:
    """Every installed entry point, read once per process (reading them costs ~25 ms, for one group
    as for all)."""
    return entry_points()


class Registry(Generic[K]):
    """The kinds of one category: ``name -> class`` from the entry point group ``group``."""

    def __init__(self, group: str, *, what: str, base: type) -> None:
        self.group, self.what, self.base = group, what, base
        self._points: dict[str, EntryPoint] | None = None
        self._loaded: dict[str, type[K]] = {}
        #: the kinds that cannot be used, with why (:class:`UnloadableKind`)
        self.broken: dict[str, str] = {}

    def _entry_points(self) -> dict[str, EntryPoint]:
        if self._points is None:
            points: dict[str, EntryPoint] = {}
            for point in sorted(_installed().select(group=self.group), key=lambda p: p.name):
                points.setdefault(point.name, point)  # the first of one seen twice (a distribution on two paths)
            self._points = points
        return self._points

    def _load(self, name: str) -> type[K]:
        """Kind ``name`` (only its module imported: a process that runs one kind loads only that one);
        :class:`UnloadableKind` for one that cannot be used."""
        if name in self.broken:
            raise UnloadableKind(self.broken[name])
        if name not in self._loaded:
            point = self._entry_points()[name]
            try:
                kind = point.load()
                fits = isinstance(kind, type) and issubclass(kind, self.base)
                why = _default_problems(getattr(kind, 'Parameters', None)) if fits else f'is not a {self.base.__name__}'
            except Exception as err:  # noqa: BLE001 - whatever a plugin's module raises as it is imported
                why = f'does not import: {type(err).__name__}: {err}'
            if why is not None:
                self.broken[name] = f"{self.what} '{name}' ({point.value}) {why}"
                raise UnloadableKind(self.broken[name])
            self._loaded[name] = cast(type[K], kind)
        return self._loaded[name]

    def kinds(self) -> dict[str, type[K]]:
        """Every usable registered kind by name (each loaded once per process, sorted by name); one
        that cannot be used is said once on stderr and left out (a model naming it is refused,
        naming why), so that a broken plugin does not stop the applications that do not use it."""
        kinds: dict[str, type[K]] = {}
        for name in self._entry_points():
            try:
                kinds[name] = self._load(name)
            except UnloadableKind as err:
                told = f'{self.group}:{name}'
                if told not in os.environ.get(TOLD, '').split():
                    print(f'warning: {err}; a model that names it is refused', file=sys.stderr)
                    os.environ[TOLD] = f'{os.environ.get(TOLD, "")} {told}'.strip()
        return kinds

    def names(self) -> list[str]:
        return list(self._entry_points())

    def plugins(self) -> list[str]:
        """The kinds other packages registered (not this project's)."""
        return [name for name, point in self._entry_points().items()
                if (point.dist.name if point.dist is not None else '').replace('-', '_') not in PROJECT]

    def __getitem__(self, name: str) -> type[K]:
        if name not in self._entry_points():
            usable = sorted(n for n in self._entry_points() if n not in self.broken)
            raise UnknownKind(f"unknown {self.what} '{name}': not one of {usable} (entry point group '{self.group}')")
        return self._load(name)

    def __contains__(self, name: object) -> bool:
        return isinstance(name, str) and name in self._entry_points()


def variants(base: type[BaseModel], registry: Registry[Any], *, field: str, suffix: str) -> Any:
    """The type "``base`` and the parameters of the kind its ``field`` names": a union with one model
    per registered kind (``<Kind><suffix>``: ``base``'s fields, then the kind's, ``field`` fixed to
    the kind's name), told apart by ``field``. This is how a kind's parameter model becomes its
    section of the application model. ``field`` may be omitted where ``base`` gives it a default."""
    members = []
    info = base.model_fields[field]
    default = None if info.is_required() else info.default
    usable = registry.kinds()
    for name, kind in usable.items():
        doc = f'{(base.__doc__ or "").strip()}\n\n``{field}: {name}``: {(kind.__doc__ or "").strip()}'
        fields: dict[str, Any] = {field: (Literal[name], Field(name if name == default else ...,
                                                              description=info.description))}
        model = derived_model(f'{kind.__name__}{suffix}', base=(kind.Parameters, base), doc=doc, **fields)
        members.append(Annotated[model, Tag(TAG.format(field=field, name=name))])
    for name, why in registry.broken.items():  # named in a model: refused with why
        members.append(Annotated[_refused(why, field=field, name=name), Tag(TAG.format(field=field, name=name))])

    def tag(value: Any) -> str | None:
        name = value.get(field, default) if isinstance(value, dict) else getattr(value, field, None)
        return TAG.format(field=field, name=name) if name in registry else None
    return Annotated[Union[tuple(members)], Discriminator(
        tag, custom_error_type='unknown_kind', custom_error_message=f'unknown {registry.what}',
        custom_error_context=_Context(field=field, what=registry.what, known=', '.join(map(repr, usable))))]


def _default_problems(parameters: Any) -> str | None:
    """What is wrong with the defaults of a kind's parameter model (a default its own rules refuse,
    which a model that leaves the field out would otherwise run with), None if nothing is."""
    if not (isinstance(parameters, type) and issubclass(parameters, BaseModel)):
        return None
    try:
        parameters.model_validate({name: info.get_default(call_default_factory=True)
                                   for name, info in parameters.model_fields.items() if not info.is_required()})
    except ValidationError as err:
        # a field's own rule; not a rule over several fields (e.g. one of two to give), which needs values
        wrong = [e for e in err.errors() if e['type'] != 'missing' and e['loc']]
        if wrong:
            return 'has defaults its own rules refuse: ' + '; '.join(
                f"{'.'.join(map(str, e['loc']))}: {e['msg']}" for e in wrong)
    return None


def _refused(why: str, *, field: str, name: str) -> type[BaseModel]:
    """A union member for kind ``name`` that cannot be used: validating it says ``why``."""
    def refuse(cls: type[BaseModel], value: Any) -> Any:
        raise ValueError(why)
    validators: dict[str, Any] = {'refuse': model_validator(mode='before')(refuse)}
    fields: dict[str, Any] = {field: (Literal[name], ...)}
    return create_model(f'Unloadable_{name}', __validators__=validators, **fields)


def derived_model(name: str, *, base: type[BaseModel] | tuple[type[BaseModel], ...], doc: str | None = None,
                  **fields: Any) -> type[BaseModel]:
    """pydantic's ``create_model`` for a model made of documented ones (``base`` and ``fields``,
    whose descriptions are given): pydantic does not look for the new class's attribute docstrings,
    which it would search for through every frame of the caller's stack (about 8 ms a model on a
    2-core VM; the application model's 25 took 0.2 s of every start)."""
    return create_model(name, __base__=base, __doc__=doc, __cls_kwargs__={'use_attribute_docstrings': False},
                        **fields)


class _Context(dict[str, int | str | float]):
    """An error context that can be hashed, as the metadata of a type in ``X | None`` must be."""

    def __hash__(self) -> int:  # type: ignore[override]
        return hash(tuple(sorted(self.items())))


def with_kind(base: type[M], registry: Registry[Any], *, field: str, values: Mapping[str, Any]) -> type[M]:
    """An entity's parameters ``base`` with those of the kind ``values`` name in ``field`` (else
    ``base``'s default kind; UnknownKind if not registered), ``field`` fixed to it: how an entity
    whose parameters depend on its kind (a chain's type, a Monitor's condition, a controller's law)
    validates them. The kind is read-only as a ROS parameter: another kind is another entity (a
    composition step swaps it)."""
    return _with_kind(base, registry, field, str(values.get(field, base.model_fields[field].default)))


@functools.cache
def _with_kind(base: type[M], registry: Registry[Any], field: str, name: str) -> type[M]:
    kind = registry[name]
    fields: dict[str, Any] = {field: (Literal[name], Field(name, description=base.model_fields[field].description,
                                                          frozen=True))}
    model = derived_model(f'{base.__qualname__.replace(".", "_")}_{name}', base=(kind.Parameters, base), **fields)
    return cast(type[M], model)
