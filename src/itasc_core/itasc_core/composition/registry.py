"""Entity kinds by name: what a model's ``kind`` field refers to (paper §4.3: a template per
kind of Functional Entity, and implementations attached to the model by metadata).

A model is data: its ``kind`` only selects one of the registered kinds, it never names code to
import. Registered are the kinds shipped with the project (the pattern_demo kinds by short name,
the iTaSC entities by ``package.module:ClassName``), kinds that installed packages declare in the
entry point group ``itasc.kinds`` (``ShortName = package.module:ClassName``), and kinds registered
in-process with :func:`register_kind` (the runtime tests' probes).
"""

from __future__ import annotations

import importlib
from importlib.metadata import EntryPoint, entry_points

from ..computation.functional_entity import FunctionalEntity

__all__ = ['resolve_kind', 'known_kind', 'register_kind', 'KINDS', 'ENTRY_POINTS', 'UnknownKind']

#: Entry point group through which other packages add kinds.
ENTRY_POINTS = 'itasc.kinds'

#: The shipped kinds: name in a model -> implementation.
KINDS: dict[str, str] = {
    'SineSource': 'itasc_core.computation.library:SineSource',
    'PController': 'itasc_core.computation.library:PController',
    'Integrator': 'itasc_core.computation.library:Integrator',
    'Sum': 'itasc_core.computation.library:Sum',
    **{target: target for target in (
        'itasc_core.itasc.entities.robot_entity:RobotEntity',
        'itasc_core.itasc.entities.scene_entity:SceneEntity',
        'itasc_core.itasc.entities.solver_entity:SolverEntity',
        'itasc_tasks.entities.vkc_entity:VKCEntity',
        'itasc_tasks.entities.constraint_output_entity:ConstraintOutputEntity',
        'itasc_tasks.entities.setpoint_generator_entity:SetpointGeneratorEntity',
        'itasc_tasks.entities.constraint_controller_entity:ConstraintControllerEntity',
        'itasc_tasks.entities.constraint_rows_entity:ConstraintRowsEntity',
        'itasc_drivers.simulated_robot:SimulatedRobot',
        'itasc_drivers.ros2_control_adapter:Ros2ControlAdapter',
        'itasc_drivers.pose_sensor:PoseSensor',
    )},
}

_REGISTERED: dict[str, type[FunctionalEntity]] = {}


class UnknownKind(LookupError):
    pass


def register_kind(name: str, cls: type[FunctionalEntity]) -> None:
    """Make ``cls`` available to models of this process as kind ``name``."""
    if not (isinstance(cls, type) and issubclass(cls, FunctionalEntity)):
        raise TypeError(f'{cls!r} is not a FunctionalEntity')
    _REGISTERED[name] = cls


def _plugins() -> dict[str, EntryPoint]:
    found: dict[str, EntryPoint] = {}
    for point in entry_points(group=ENTRY_POINTS):
        found[point.name] = point
        found.setdefault(point.value, point)
    return found


def known_kind(kind: str) -> bool:
    """Whether ``kind`` is registered (nothing is imported)."""
    return kind in _REGISTERED or kind in KINDS or kind in _plugins()


def resolve_kind(kind: str) -> type[FunctionalEntity]:
    """The Functional Entity class of registered kind ``kind``; :class:`UnknownKind` otherwise."""
    if kind in _REGISTERED:
        return _REGISTERED[kind]
    plugin = None if kind in KINDS else _plugins().get(kind)
    if kind not in KINDS and plugin is None:
        shipped = sorted(k for k in KINDS if ':' not in k)
        raise UnknownKind(f"unknown entity kind '{kind}': not one of {shipped}, nor a kind registered in the "
                          f"entry point group '{ENTRY_POINTS}'")
    try:
        if plugin is not None:
            cls = plugin.load()
        else:
            module_name, _, class_name = KINDS[kind].partition(':')
            cls = getattr(importlib.import_module(module_name), class_name)
    except (ImportError, AttributeError) as err:
        raise UnknownKind(f"entity kind '{kind}' cannot be loaded: {err}") from None
    if not (isinstance(cls, type) and issubclass(cls, FunctionalEntity)):
        raise UnknownKind(f"entity kind '{kind}' is not a FunctionalEntity")
    return cls
