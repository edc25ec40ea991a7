"""Generated applications for the scaling benchmarks (issue #9): N Tasks on one robot.

Tasks cycle through the three chain types of the DSL, every one active from the start (no Running
sub-FSM): a Cartesian position Task towards a target of its own (priority 1), a distance
inequality keeping a link away from a far obstacle (priority 0), a joint posture Task holding one
joint (priority 2). ``robot='panda'`` (7 DOF) or ``'talos'`` (38 DOF: 32 joints on a free-flyer
base, from example-robot-data, ``requirements/bench.txt``).
"""

from __future__ import annotations

import pathlib

import yaml

__all__ = ['application']

CONFIG = pathlib.Path(__file__).resolve().parents[1] / 'config'


def _panda() -> tuple[dict, dict, list[str], list[str]]:
    robot = {'name': 'panda', 'urdf': str(CONFIG / 'robots' / 'panda.urdf'),
             'frames': [{'name': 'tcp', 'link': 'panda_hand_tcp'}]}
    initial = yaml.safe_load((CONFIG / 'robots' / 'panda_ready.yaml').read_text())
    links = [f'panda_link{i}' for i in range(2, 8)]
    joints = [f'panda_joint{i}' for i in range(1, 8)]
    return robot, initial, links, joints


def _talos() -> tuple[dict, dict, list[str], list[str]]:
    import example_robot_data  # noqa: F401 - ImportError: not installed (requirements/bench.txt)
    from example_robot_data.robots_loader import TalosLoader
    urdf = pathlib.Path(TalosLoader().df_path).resolve()
    robot = {'name': 'talos', 'urdf': str(urdf), 'base': 'free_flyer',
             'frames': [{'name': 'tcp', 'link': 'gripper_left_base_link'}]}
    links = ['gripper_right_base_link', 'torso_2_link', 'arm_left_4_link', 'arm_right_4_link', 'head_2_link']
    joints = ['torso_1_joint', 'arm_left_2_joint', 'arm_right_2_joint', 'arm_left_4_joint', 'arm_right_4_joint',
              'head_1_joint']
    return robot, {}, links, joints


def application(*, tasks: int, robot: str = 'panda', rate: float = 100.0) -> dict:
    """The application model (as YAML data) with ``tasks`` Tasks on ``robot``."""
    model, initial, links, joints = _panda() if robot == 'panda' else _talos()
    name = model['name']
    objects, entries = [], []
    for i in range(tasks):
        kind = i % 3
        if kind == 0:
            objects.append({'name': f'target{i}', 'xyz': [0.45 + 0.02 * (i % 5), 0.1 * (i % 3 - 1), 0.4]})
            entries.append({'name': f'Reach{i}', 'type': 'cartesian', 'o1': f'target{i}', 'o2': f'{name}/tcp',
                            'outputs': ['x', 'y', 'z'], 'controller': {'kind': 'p', 'kp': 1.0, 'max_output': 0.2},
                            'setpoint': {'kind': 'fixed', 'value': [0.0, 0.0, 0.0]}, 'weights': 0.1, 'priority': 1})
        elif kind == 1:
            objects.append({'name': f'obstacle{i}', 'xyz': [2.0 + 0.1 * i, 1.0, 1.0]})
            entries.append({'name': f'Avoid{i}', 'type': 'distance', 'o1': f'obstacle{i}',
                            'o2': f'{name}/{links[i % len(links)]}',
                            'constraint': 'inequality', 'd_min': 0.05, 'controller': {'kind': 'p', 'kp': 5.0},
                            'priority': 0})
        else:
            entries.append({'name': f'Posture{i}', 'type': 'joint', 'joints': [joints[i % len(joints)]],
                            'controller': {'kind': 'p', 'kp': 1.0}, 'weights': 0.01, 'priority': 2})
    program = {'name': 'itasc', 'robots': [model], 'objects': objects, 'tasks': entries,
               'solver': {'kind': 'qp', 'backend': 'daqp'}}
    driver = {'robot': name, 'kind': 'simulated', **({'initial': initial} if initial else {})}
    return {'application': {'name': f'scale_{robot}_{tasks}', 'rate': rate, 'program': program,
                            'drivers': [driver]}}
