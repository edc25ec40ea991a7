"""Replay of a recorded run as a regression test (paper §4.1 "Solver", §2.2: the Solver turns the
constraint rows of all Tasks into joint velocity commands, tick by tick).

``itasc-replay BAG [--app MODEL] [--tolerance TOL]`` runs the application's Solver entity (the
real ``SolverEntity``, configured from the model as the Composer and Configurator would) offline
on the inputs recorded in BAG, tick by tick, as fast as it computes: at every recorded tick ``t``
(a stamp of ``<program>/Solver/command``) it is given what it read live — the constraint rows of
every Task and the Scene's joint state stamped up to ``t`` — and computes. The new commands are
compared with the recorded ones; the largest differences are printed per joint, and the exit code
is 1 past ``--tolerance`` (0 otherwise). Replaying with an unchanged model reproduces the commands
to round-off; a changed Solver gain (``joint_weights``, ``damping``, ``regularization``,
``position_limit_gain``) or solver kind shows as differences.

Scope: the Tasks are not re-run; their recorded rows are the Solver's input (a changed Task gain
is not replayed).
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ['main', 'ReplayError', 'SolverSite', 'solver_sites', 'replay']


class ReplayError(Exception):
    """BAG or MODEL cannot be replayed; the message names what is missing."""


@dataclass(frozen=True)
class SolverSite:
    """A Solver of the model: its composite's namespace and parameters (initial configuration applied)."""

    namespace: str
    composite: str
    name: str
    parameters: dict[str, Any]


def solver_sites(model) -> list[SolverSite]:
    from itasc_core.composition.model import walk
    from itasc_core.composition.registry import resolve_kind
    from itasc_core.itasc.entities.solver_entity import SolverEntity

    sites = []
    for path, composite in walk(model):
        for leaf in composite.leaves:
            if issubclass(resolve_kind(leaf.kind), SolverEntity):
                params = dict(leaf.parameters)
                for config in composite.configure:
                    params.update(composite.configurations[config].get(leaf.name, {}))
                sites.append(SolverSite(path, composite.name, leaf.name, params))
    return sites


def _stamp(msg) -> float:
    s = msg.header.stamp if hasattr(msg, 'header') else msg.stamp
    return s.sec + 1e-9 * s.nanosec


def _read(bag: Path, topics: set[str]) -> dict[str, list]:
    """rclpy messages of ``topics``, in recorded order."""
    import importlib

    from rclpy.serialization import deserialize_message
    from rosbags.highlevel import AnyReader

    found: dict[str, list] = {t: [] for t in topics}
    try:
        with AnyReader([bag]) as reader:
            wanted = [c for c in reader.connections if c.topic in topics]
            classes = {}
            for c in wanted:
                package, kind, name = c.msgtype.split('/')
                classes[c.topic] = getattr(importlib.import_module(f'{package}.{kind}'), name)
            for c, _, raw in reader.messages(connections=wanted):
                found[c.topic].append(deserialize_message(bytes(raw), classes[c.topic]))
    except Exception as err:  # rosbags raises several kinds for an unreadable bag
        raise ReplayError(f'{bag}: not a readable bag ({type(err).__name__}: {err})') from None
    return found


def replay(bag: Path, model, *, site: SolverSite) -> dict[str, Any]:
    """Re-run the Solver at ``site`` on the inputs recorded in ``bag``. Returns the ticks, the
    joint names, and the recorded and replayed commands (ticks x joints)."""
    import rclpy

    from itasc_core.entity import CompositeContext
    from itasc_core.itasc.entities.solver_entity import SolverEntity

    prefix = f'{site.namespace}/{site.name}'
    command_topic = f'{prefix}/command'
    scene_topic = f'{site.namespace}/Scene/joint_state'
    with_rows = [t for t in _topic_names(bag) if t.startswith(site.namespace + '/') and t.endswith('/Rows/rows')]
    recorded = _read(bag, {command_topic, scene_topic, *with_rows})
    if not recorded[command_topic]:
        raise ReplayError(f'{bag}: no messages on {command_topic} (is it a recording of {model.name}?)')
    commands: dict[float, Any] = {}
    for msg in recorded[command_topic]:
        commands.setdefault(_stamp(msg), msg)   # the last one of a run repeats its tick (disengage)
    inputs = sorted(((_stamp(m), topic, m) for topic in (scene_topic, *with_rows) for m in recorded[topic]),
                    key=lambda item: item[0])

    rclpy.init(domain_id=_private_domain())   # a domain of its own: never joins a running application
    solver = None
    try:
        solver = SolverEntity(site.name, composite=CompositeContext(name=site.composite, namespace=site.namespace),
                              parameters=site.parameters)
        live, again, k = [], [], 0
        for t, msg in sorted(commands.items()):
            while k < len(inputs) and inputs[k][0] <= t:
                _, topic, sample = inputs[k]
                port = solver.inputs['joint_state' if topic == scene_topic else 'rows']
                port.deliver(sample, topic)
                k += 1
            solver.update(t)
            names = list(msg.name)
            out = solver.outputs['command'].last
            by_name = dict(zip(out.name, out.velocity))
            live.append(np.asarray(msg.velocity, dtype=float))
            again.append(np.array([by_name.get(n, np.nan) for n in names]))
        return {'ticks': sorted(commands), 'joints': names, 'recorded': np.array(live), 'replayed': np.array(again)}
    finally:
        if solver is not None:
            solver.destroy_node()
        rclpy.try_shutdown()


def _private_domain() -> int:
    import os
    return 200 + os.getpid() % 30   # 200..229: above the ids ROS tools and our tests use


def _topic_names(bag: Path) -> list[str]:
    from rosbags.highlevel import AnyReader
    try:
        with AnyReader([bag]) as reader:
            return [c.topic for c in reader.connections]
    except Exception as err:
        raise ReplayError(f'{bag}: not a readable bag ({type(err).__name__}: {err})') from None


def _app_of(bag: Path) -> str:
    names = {t.split('/')[1] for t in _topic_names(bag) if t.count('/') >= 2}
    if len(names) != 1:
        raise ReplayError(f'{bag}: cannot tell the application from its topics ({sorted(names)}); give --app')
    return names.pop()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog='itasc-replay', description=__doc__.split('\n\n')[0])
    parser.add_argument('bag', type=Path, help='a recording: bag folder or .mcap file')
    parser.add_argument('--app', default=None, help='application name or model path (default: the recorded one)')
    parser.add_argument('--tolerance', type=float, default=1e-9, help='largest allowed command difference (rad/s)')
    args = parser.parse_args(argv)
    from itasc_core.composition.loader import ModelError

    from .apps import load_composition
    try:
        if not args.bag.exists():
            raise ReplayError(f'{args.bag}: no such bag')
        model = load_composition(args.app or _app_of(args.bag))
        sites = solver_sites(model)
        if not sites:
            raise ReplayError(f'model {model.name} has no Solver')
        worst = 0.0
        for site in sites:
            result = replay(args.bag, model, site=site)
            diff = np.abs(result['replayed'] - result['recorded'])
            diff = np.where(np.isnan(diff), np.inf, diff)
            print(f'{site.namespace}/{site.name}: {len(result["ticks"])} ticks replayed')
            for j, name in enumerate(result['joints']):
                k = int(np.argmax(diff[:, j]))
                print(f'  {name:24s} largest difference {diff[k, j]:.3e} rad/s at t={result["ticks"][k]:.3f} s'
                      f' (recorded {result["recorded"][k, j]:+.6f}, replayed {result["replayed"][k, j]:+.6f})')
            worst = max(worst, float(diff.max()))
    except (ModelError, ReplayError) as err:
        print(f'error: {err}', file=sys.stderr)
        return 2
    verdict = 'within' if worst <= args.tolerance else 'BEYOND'
    print(f'largest difference {worst:.3e} rad/s: {verdict} the tolerance {args.tolerance:g}')
    return 0 if worst <= args.tolerance else 1


if __name__ == '__main__':
    sys.exit(main())
