"""The picture tools: ``itasc-plot`` draws a recorded run (task errors, joints against their
limits, every composite's life cycle) and ``itasc-graph`` draws a composition as nested clusters
(paper Fig. 1/2)."""
import math
import os
import pathlib
import shutil
import subprocess
import sys
import textwrap

import pytest

os.environ.setdefault('ROS_DOMAIN_ID', str(1 + os.getpid() % 101))  # conftest.py normally sets it

from PIL import Image

JOINTS = [f'panda_joint{i}' for i in range(1, 8)]
SAFETY_RED = (0xe3, 0x1a, 0x1c)     # plot.TOP_LEVEL_COLOURS['Safety']
RUN_GREEN = (0x33, 0xa0, 0x2c)      # plot.TOP_LEVEL_COLOURS['Run']
LIMIT_RED = (0xd6, 0x27, 0x28)      # matplotlib 'tab:red', the limit lines

# (time, composite topic, state, event): the life cycle of three nested composites
LIFECYCLE = [
    (0.0, '/app/state', 'Active.Configure.Configuring.DeployEntities', ''),
    (0.4, '/app/state', 'Active.Configure.Configured.ConnectEntities', 'e_itasc_configured'),
    (1.0, '/app/state', 'Active.Start.Starting', 'e_app_start'),
    (1.5, '/app/state', 'Active.Run.Running.approach', 'e_itasc_running'),
    (4.0, '/app/state', 'Active.Run.Running.grasp', 'e_approach_done'),
    (6.0, '/app/state', 'Safety', 'e_emergency'),
    (0.1, '/app/itasc/state', 'Active.Configure.Configuring.DeployEntities', 'e_itasc_configure'),
    (0.3, '/app/itasc/state', 'Active.Configure.Configured.NotifyConfigured', 'e_tasks_configured'),
    (1.1, '/app/itasc/state', 'Active.Start.Started', 'e_itasc_start'),
    (1.4, '/app/itasc/state', 'Active.Run.Running', 'e_itasc_run'),
    (6.0, '/app/itasc/state', 'Safety', 'e_emergency'),
    (0.2, '/app/itasc/ApproachObject/state', 'Active.Configure.Configuring.ConfigureEntities',
     'e_ApproachObject_configure'),
    (1.2, '/app/itasc/ApproachObject/state', 'Active.Run.Running', 'e_ApproachObject_run'),
    (4.0, '/app/itasc/ApproachObject/state', 'Active.Stop.Stopped.Cleanup',
     'e_ApproachObject_stop'),
]


def _urdf() -> str:
    """A 7-joint serial arm whose joints have position limits +-(2.0 + 0.1 i), velocity 1.5."""
    joints = []
    for i, name in enumerate(JOINTS):
        parent = 'base' if i == 0 else f'l{i - 1}'
        bound = 2.0 + 0.1 * i
        joints.append(f'<link name="l{i}"/><joint name="{name}" type="revolute">'
                      f'<parent link="{parent}"/><child link="l{i}"/>'
                      f'<limit lower="{-bound}" upper="{bound}" velocity="1.5" effort="10"/>'
                      '</joint>')
    return '<robot name="arm7"><link name="base"/>' + ''.join(joints) + '</robot>'


def write_run(path: pathlib.Path, duration: float = 8.0) -> None:
    """A small recording as the Recorder writes it: rosbag2-style schemas, CDR messages.

    Messages are serialized with rosbags from the very schemas written to the file (rclpy's
    serialize_message on these wheels appends stray bytes to some types, e.g. JointState).
    """
    import numpy as np
    from mcap.writer import Writer
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    from itasc_bringup.recording.definitions import definition as full_definition

    type_names = ('itasc_msgs/msg/CoordinatorState', 'itasc_msgs/msg/TaskState',
                  'sensor_msgs/msg/JointState')
    definitions = {name: full_definition(name) for name in type_names}
    store = get_typestore(Stores.EMPTY)
    for name, (_, text) in definitions.items():
        store.register(get_types_from_msg(text, name))
    T = store.types
    Time, Header = T['builtin_interfaces/msg/Time'], T['std_msgs/msg/Header']
    floats = lambda values: np.array(values, dtype=np.float64)  # noqa: E731

    def time(t: float):
        return Time(sec=int(t), nanosec=int(round((t % 1) * 1e9)) % 1_000_000_000)

    messages = []   # (t, topic, type, msg)
    for t, topic, state, event in LIFECYCLE:
        messages.append((t, topic, 'itasc_msgs/msg/CoordinatorState', T[
            'itasc_msgs/msg/CoordinatorState'](stamp=time(t), composite=topic.split('/')[-2],
                                               state=state, previous_state='', event=event)))
    for k in range(int(duration * 50)):
        t = k / 50
        messages.append((t, '/app/robot/joint_states', 'sensor_msgs/msg/JointState', T[
            'sensor_msgs/msg/JointState'](
                header=Header(stamp=time(t), frame_id=''), name=JOINTS,
                position=floats([0.5 * math.sin(t + j) for j in range(7)]),
                velocity=floats([0.5 * math.cos(t + j) for j in range(7)]), effort=floats([]))))
        decay = math.exp(-t)
        for task, error, active in (
                ('ApproachObject', [0.3 * decay * (j + 1) for j in range(6)], t < 4.0),
                ('AvoidObstacle', [0.05 * math.sin(3 * t)], True)):
            messages.append((t, f'/app/itasc/{task}/task_state', 'itasc_msgs/msg/TaskState', T[
                'itasc_msgs/msg/TaskState'](
                    stamp=time(t), task=task, output=floats([]), setpoint=floats([]),
                    error=floats(error), error_norm=float(np.linalg.norm(error)), active=active)))
    messages.sort(key=lambda m: m[0])
    t0 = 1_700_000_000_000_000_000
    with open(path, 'wb') as f:
        writer = Writer(f)
        writer.start(profile='ros2', library='test')
        schemas, channels = {}, {}
        for t, topic, type_name, msg in messages:
            if type_name not in schemas:
                encoding, text = definitions[type_name]
                schemas[type_name] = writer.register_schema(type_name, encoding, text.encode())
            if topic not in channels:
                channels[topic] = writer.register_channel(topic, 'cdr', schemas[type_name], {
                    'offered_qos_profiles': ''})
            stamp = t0 + int(t * 1e9)
            writer.add_message(channels[topic], log_time=stamp, publish_time=stamp,
                               data=bytes(store.serialize_cdr(msg, type_name)))
        writer.finish()


def _has_colour(path: pathlib.Path, rgb: tuple[int, int, int], tolerance: int = 6) -> int:
    """Number of pixels of ``path`` within ``tolerance`` of ``rgb``."""
    image = Image.open(path).convert('RGB')
    return sum(count for count, pixel in image.getcolors(maxcolors=1 << 20)
               if all(abs(a - b) <= tolerance for a, b in zip(pixel, rgb)))


@pytest.fixture(scope='module')
def run_mcap(tmp_path_factory) -> pathlib.Path:
    path = tmp_path_factory.mktemp('run') / 'run.mcap'
    write_run(path)
    return path


def test_plot_writes_task_joint_and_lifecycle_pictures(run_mcap, tmp_path, capsys):
    from itasc_bringup.plot import main

    urdf = tmp_path / 'arm.urdf'
    urdf.write_text(_urdf())
    out = tmp_path / 'plots'
    assert main([str(run_mcap), '--out', str(out), '--urdf', str(urdf)]) == 0
    printed = capsys.readouterr().out.split()
    names = sorted(p.name for p in out.iterdir())
    assert names == ['index.html', 'joints_app_robot_joint_states.png', 'lifecycle.png', 'task_errors.png']
    assert sorted(pathlib.Path(p).name for p in printed) == names
    # the overview page shows every picture, task meanings first
    page = (out / 'index.html').read_text()
    first = ('task_errors.png', 'joints_app_robot_joint_states.png', 'lifecycle.png')
    shown = [page.index(f'<img src="{name}"') for name in first]
    assert shown == sorted(page.index(f'<img src="{n}"') for n in names[1:])
    names.remove('index.html')
    for name in names:
        path = out / name
        assert path.stat().st_size > 20_000, name
        width, height = Image.open(path).size
        assert width >= 800 and height >= 300, (name, width, height)
    # one row per task (+ the norms) and one row per joint: taller with more of them
    assert Image.open(out / 'task_errors.png').size[1] >= 3 * 200
    assert Image.open(out / 'joints_app_robot_joint_states.png').size[1] >= 7 * 150
    # the life cycle shows the Run segments and the Safety the composites ended in
    assert _has_colour(out / 'lifecycle.png', RUN_GREEN) > 2000
    assert _has_colour(out / 'lifecycle.png', SAFETY_RED) > 500
    # limits from the URDF are drawn as red lines (no other red in the joint picture)
    assert _has_colour(out / 'joints_app_robot_joint_states.png', LIMIT_RED, 30) > 500


def test_plot_default_out_dir_and_no_limits_without_urdf(run_mcap, tmp_path):
    from itasc_bringup.plot import main

    mcap = tmp_path / 'copy.mcap'
    shutil.copy(run_mcap, mcap)
    assert main([str(mcap)]) == 0
    out = tmp_path / 'copy_plots'
    assert (out / 'lifecycle.png').is_file()
    assert _has_colour(out / 'joints_app_robot_joint_states.png', LIMIT_RED, 30) < 50


@pytest.mark.parametrize('content', [None, b'not an mcap file at all', b''])
def test_plot_bad_file_is_a_clear_error(tmp_path, capsys, content):
    from itasc_bringup.plot import main

    path = tmp_path / 'broken.mcap'
    if content is not None:
        path.write_bytes(content)
    assert main([str(path)]) == 2
    err = capsys.readouterr().err
    assert err.startswith('itasc-plot: error:') and str(path) in err
    assert 'Traceback' not in err


def test_plot_needs_no_ros_install(run_mcap, tmp_path):
    """Our own message types decode from the schemas in the file: no rclpy, no itasc_msgs."""
    blocker = textwrap.dedent('''
        import sys, importlib.abc
        ROS = ('rclpy', 'rosidl', 'itasc_msgs', 'sensor_msgs', 'std_msgs', 'builtin_interfaces',
               'ament_index_python', 'rpyutils')
        class Block(importlib.abc.MetaPathFinder):
            def find_spec(self, name, path, target=None):
                if name.split('.')[0].startswith(ROS):
                    raise ImportError(f'{name} blocked: no ROS here')
        sys.meta_path.insert(0, Block())
        from itasc_bringup.plot import main
        sys.exit(main(sys.argv[1:]))
    ''')
    env = {k: v for k, v in os.environ.items() if k != 'AMENT_PREFIX_PATH'}
    out = tmp_path / 'plots'
    result = subprocess.run([sys.executable, '-c', blocker, str(run_mcap), '--out', str(out)],
                            env=env, capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    assert (out / 'task_errors.png').stat().st_size > 20_000


def _three_level_model():
    from itasc_core.composition.model import CompositeModel

    task = lambda name: {  # noqa: E731
        'name': name,
        'entities': [{'name': 'vkc', 'kind': 'VKC'}, {'name': 'co', 'kind': 'ConstraintOutput'},
                     {'name': 'cc', 'kind': 'PID'}, {'name': 'sg', 'kind': 'FixedSetpoint'}],
        'connections': [{'from': 'vkc.chi_f', 'to': 'co.chi_f'}, {'from': 'co.y', 'to': 'cc.y'},
                        {'from': 'sg.y_d', 'to': 'cc.y_d'}],
        'exports': {'rows': 'cc.rows', 'pose': 'vkc.pose'},
    }
    return CompositeModel.model_validate({
        'name': 'application',
        'entities': [
            {'name': 'itasc',
             'entities': [task('ApproachObject'), task('AvoidObstacle'),
                          {'name': 'robot', 'kind': 'Robot'},
                          {'name': 'solver', 'kind': 'WDLSSolver'}],
             'connections': [{'from': 'ApproachObject.rows', 'to': 'solver.rows'},
                             {'from': 'AvoidObstacle.rows', 'to': 'solver.rows'}],
             'exports': {'qdot': 'solver.qdot', 'q': 'robot.q'},
             'monitors': [{'name': 'error_monitor', 'watch': 'ApproachObject.rows',
                           'condition': 'above', 'threshold': 0.1,
                           'event': 'e_max_pos_tracking_error_exc'}]},
            {'name': 'driver', 'kind': 'SimulatedRobot'},
        ],
        'connections': [{'from': 'itasc.qdot', 'to': 'driver.qdot'},
                        {'from': 'driver.q', 'to': 'itasc.q'}],
    })


def test_graph_draws_nested_composites(tmp_path):
    from itasc_bringup.graph import draw

    model = _three_level_model()
    svg, png = draw(model, tmp_path / 'graph')
    text = svg.read_text()
    assert svg.stat().st_size > 10_000 and png.stat().st_size > 20_000
    width, height = Image.open(png).size
    assert width > 800 and height > 400
    # one cluster per composite, nested three deep, each with the pattern's roles
    for cluster in ('/application', '/application/itasc', '/application/itasc/ApproachObject',
                    '/application/itasc/AvoidObstacle'):
        assert f'cluster_{cluster}</title>' in text
        assert f'{cluster}/Coordinator</title>' in text and f'{cluster}/Composer</title>' in text
    assert text.count('>Coordinator</text>') == 4 and text.count('>Scheduler</text>') == 4
    # the paper's colours: Coordinator blue, Composer red, Monitor purple
    assert 'fill="#3b6fd1"' in text and 'fill="#d64541"' in text and 'fill="#8e44ad"' in text
    # data flow labelled with port names, through the itasc composite's exports
    assert 'qdot → qdot' in text and 'rows → rows' in text
    assert '/application/itasc/solver&#45;&gt;/application/driver' in text


def test_graph_cli_rejects_unknown_app(tmp_path, capsys):
    from itasc_bringup.graph import main

    assert main([str(tmp_path / 'missing.yaml'), '--out', str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err.startswith('itasc-graph: error:') and 'Traceback' not in err
