"""Editing a copy of the shipped model files in tests (the ``config`` fixture of test/unit), or a
shipped application written out with other Driver fields."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Callable

import yaml

__all__ = ['edit_yaml', 'app_with_drivers', 'three_joint_arm', 'two_arms']

CONFIG = Path(__file__).resolve().parents[2] / 'config'


def edit_yaml(file: Path, change: Callable[[Any], None]) -> None:
    """Rewrite the YAML ``file`` with ``change(data)`` applied to it."""
    data = yaml.safe_load(file.read_text())
    change(data)
    file.write_text(yaml.safe_dump(data, sort_keys=False))


def app_with_drivers(app: str, directory: Path, **fields: Any) -> Path:
    """The shipped application ``app`` written to ``directory`` with ``fields`` set on each of its
    Drivers (e.g. ``silent_after=1.0``); its includes still name the shipped files."""
    data = yaml.safe_load((CONFIG / 'apps' / f'{app}.yaml').read_text())
    application = data['application']
    if isinstance(application.get('program'), dict) and 'include' in application['program']:
        application['program']['include'] = str(CONFIG / 'apps' / application['program']['include'])
    for driver in application['drivers']:
        driver.update(fields)
    path = directory / f'{app}.yaml'
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def three_joint_arm(*, prefix: str = '') -> str:
    """The URDF of a robot that is not a Panda: three revolute joints ``<prefix>j1..j3`` (z, y, y)
    and a link ``flange`` 1.1 m above its base when they are at 0."""
    return f"""<?xml version="1.0"?>
<robot name="arm">
  <link name="base_link"/><link name="l1"/><link name="l2"/><link name="l3"/><link name="flange"/>
  <joint name="{prefix}j1" type="revolute"><parent link="base_link"/><child link="l1"/><origin xyz="0 0 0.3"/>
    <axis xyz="0 0 1"/><limit lower="-3" upper="3" velocity="2" effort="1"/></joint>
  <joint name="{prefix}j2" type="revolute"><parent link="l1"/><child link="l2"/><axis xyz="0 1 0"/>
    <limit lower="-3" upper="3" velocity="2" effort="1"/></joint>
  <joint name="{prefix}j3" type="revolute"><parent link="l2"/><child link="l3"/><origin xyz="0 0 0.4"/>
    <axis xyz="0 1 0"/><limit lower="-3" upper="3" velocity="2" effort="1"/></joint>
  <joint name="{prefix}j4" type="fixed"><parent link="l3"/><child link="flange"/><origin xyz="0 0 0.4"/></joint>
</robot>
"""


def two_arms(directory: Path, *, name: str, drivers: list[dict[str, Any]]) -> Path:
    """An application ``name`` of two :func:`three_joint_arm` robots far from the origin, ``arm``
    at (2, 1, 0) and ``other`` (joints ``b_j1..b_j3``) at (2, -1, 0), each with a Task reaching an
    object of its own (``Reach``, ``Other``), driven by ``drivers`` (the robots in their order),
    written with the two URDFs to ``directory``; its path."""
    (directory / 'arm.urdf').write_text(three_joint_arm(), encoding='utf-8')
    (directory / 'other.urdf').write_text(three_joint_arm(prefix='b_'), encoding='utf-8')
    robots = {'arm': [2.0, 1.0, 0.0], 'other': [2.0, -1.0, 0.0]}
    objects = {'arm': ('target', [2.3, 1.2, 0.6]), 'other': ('goal', [2.2, -1.2, 0.7])}
    tasks = {'arm': 'Reach', 'other': 'Other'}
    order = [d['robot'] for d in drivers]
    program = {
        'name': 'itasc',
        'robots': [{'name': r, 'urdf': str(directory / f'{r}.urdf'), 'xyz': robots[r],
                    'frames': [{'name': 'tool', 'link': 'flange'}]} for r in order],
        'objects': [{'name': objects[r][0], 'xyz': objects[r][1]} for r in order],
        'tasks': [{'name': tasks[r], 'type': 'cartesian', 'o1': objects[r][0], 'o2': f'{r}/tool',
                   'outputs': ['x', 'y', 'z'], 'controller': {'kind': 'p', 'kp': 2.0},
                   'setpoint': {'kind': 'minimum_jerk', 'pose': {'xyz': [0, 0, 0]}, 'duration': 1.0}}
                  for r in order],
        'solver': {'kind': 'qp'}}
    path = directory / f'{name}.yaml'
    path.write_text(yaml.safe_dump({'application': {'name': name, 'rate': 100, 'program': program,
                                                    'drivers': drivers}}, sort_keys=False), encoding='utf-8')
    return path
