"""``--record DIR`` writes a rosbag2 bag folder that ROS tools open as a bag: rosbags opens it as a
rosbag2 bag, ``rosbags-convert`` round-trips it, its metadata.yaml is what rosbag2 Jazzy writes
(field by field against test/data/rosbag2_jazzy_metadata.yaml), with the type hashes ROS computes
and the publishers' QoS; ``--record FILE.mcap`` still writes a bare MCAP file."""
import pathlib
import subprocess
import sys
import time

import pytest
import yaml
from ros_client import spin_until

import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

REFERENCE = pathlib.Path(__file__).parent / 'data' / 'rosbag2_jazzy_metadata.yaml'
N = 25


def _record(context, path: pathlib.Path) -> dict[str, str]:
    """Record N joint states, N events and one latched state to ``path``; returns the type hashes
    that rclpy reports for the publishers, by topic."""
    from itasc_msgs.msg import CoordinatorState, Event
    from sensor_msgs.msg import JointState

    from itasc_bringup.recording import Recorder
    from itasc_core.communication.qos import EVENT_QOS

    app = rclpy.create_node('bag_app', context=context)
    joints = app.create_publisher(JointState, '/app/robot/joint_states', 10)
    latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL,
                         reliability=ReliabilityPolicy.RELIABLE)
    state = app.create_publisher(CoordinatorState, '/app/state', latched)
    state.publish(CoordinatorState(composite='app', state='Active.Run.Running'))
    recorder = Recorder(path, prefix='/app', context=context, scan_period=0.05)
    recorder.record('/app/events', 'itasc_msgs/msg/Event', qos=EVENT_QOS)  # known before publishing
    events = app.create_publisher(Event, '/app/events', EVENT_QOS)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(app)
    executor.add_node(recorder)
    try:
        assert spin_until(executor, lambda: joints.get_subscription_count() and events.get_subscription_count()
                           and recorder.counts.get('/app/state') == 1, 10.0), recorder.topics
        for i in range(N):
            joints.publish(JointState(name=['j1'], position=[0.1 * i]))
            events.publish(Event(name=f'e_{i}', seq=i + 1))
            executor.spin_once(timeout_sec=0.0)
            time.sleep(0.01)
        assert spin_until(executor, lambda: recorder.counts['/app/robot/joint_states'] == N
                           and recorder.counts['/app/events'] == N, 10.0), recorder.counts
        assert recorder.last('/app/events').name == f'e_{N - 1}'
        assert recorder.last('/app/state').state == 'Active.Run.Running'
        hashes = {t: str(app.get_publishers_info_by_topic(t)[0].topic_type_hash)
                  for t in ('/app/robot/joint_states', '/app/events', '/app/state')}
    finally:
        executor.shutdown()
        recorder.destroy_node()
        app.destroy_node()
    return hashes


def _same_shape(ours, reference, where: str = 'rosbag2_bagfile_information') -> None:
    """Same keys in the same order, same kinds of values, at every level."""
    if isinstance(reference, dict):
        assert isinstance(ours, dict), where
        assert list(ours) == list(reference), f'{where}: keys {list(ours)} != {list(reference)}'
        for key in reference:
            _same_shape(ours[key], reference[key], f'{where}.{key}')
    elif isinstance(reference, list):
        assert isinstance(ours, list) and ours, where
        for item in ours:
            _same_shape(item, reference[0], f'{where}[]')
    else:
        assert type(ours) is type(reference), f'{where}: {ours!r} is not a {type(reference).__name__}'


def test_a_recorded_folder_is_a_rosbag2_jazzy_bag(context, tmp_path):
    from itasc_core.communication.qos import EVENT_DEPTH
    bag = tmp_path / 'run'
    hashes = _record(context, bag)
    assert sorted(p.name for p in bag.iterdir()) == ['metadata.yaml', 'run_0.mcap']

    # metadata.yaml, field by field as rosbag2 Jazzy writes it
    reference = yaml.safe_load(REFERENCE.read_text())['rosbag2_bagfile_information']
    text = (bag / 'metadata.yaml').read_text()
    info = yaml.safe_load(text)['rosbag2_bagfile_information']
    _same_shape(info, reference)
    for key in ('version', 'storage_identifier', 'compression_format', 'compression_mode', 'custom_data', 'ros_distro'):
        assert info[key] == reference[key], key
    topics = {t['topic_metadata']['name']: t for t in info['topics_with_message_count']}
    assert {name: t['message_count'] for name, t in topics.items()} == {
        '/app/robot/joint_states': N, '/app/events': N, '/app/state': 1}
    assert info['message_count'] == 2 * N + 1 == info['files'][0]['message_count']
    assert info['relative_file_paths'] == [info['files'][0]['path']] == ['run_0.mcap']
    for name, t in topics.items():   # the hash ROS itself computes for the publishers' type
        assert t['topic_metadata']['type_description_hash'] == hashes[name]
        assert t['topic_metadata']['serialization_format'] == 'cdr'
    assert topics['/app/state']['topic_metadata']['offered_qos_profiles'][0]['durability'] == 'transient_local'
    assert topics['/app/events']['topic_metadata']['offered_qos_profiles'][0]['depth'] == EVENT_DEPTH

    # the MCAP file: times agree with metadata.yaml; rosbag2's metadata record is there
    from mcap.reader import make_reader
    with open(bag / 'run_0.mcap', 'rb') as f:
        reader = make_reader(f)
        log_times = [m.log_time for _, _, m in reader.iter_messages()]
        records = {m.name: m.metadata for m in reader.iter_metadata()}
        channels = {c.topic: c for c in reader.get_summary().channels.values()}
    assert info['starting_time']['nanoseconds_since_epoch'] == min(log_times)
    assert info['duration']['nanoseconds'] == max(log_times) - min(log_times) > 0
    assert yaml.safe_load(records['rosbag2']['serialized_metadata']) == info
    assert records['rosbag2']['ros_distro'] == 'jazzy'
    assert channels['/app/events'].metadata['topic_type_hash'] == hashes['/app/events']

    # rosbags opens the folder as a rosbag2 bag and decodes every message
    from rosbags.highlevel import AnyReader
    from rosbags.rosbag2 import Reader
    with Reader(bag) as reader:
        assert reader.message_count == 2 * N + 1
        assert {c.topic: c.digest for c in reader.connections} == hashes
    with AnyReader([bag]) as reader:
        decoded = [(c.topic, reader.deserialize(raw, c.msgtype)) for c, _, raw in reader.messages()]
    assert [m.name for t, m in decoded if t == '/app/events'] == [f'e_{i}' for i in range(N)]


def test_rosbags_convert_round_trips_the_bag(context, tmp_path):
    from rosbags.highlevel import AnyReader

    bag = tmp_path / 'run'
    _record(context, bag)
    ros1, back = tmp_path / 'run.bag', tmp_path / 'back'
    for src, dst in ((bag, ros1), (ros1, back)):
        done = subprocess.run([str(pathlib.Path(sys.executable).parent / 'rosbags-convert'), '--src', str(src),
                               '--dst', str(dst)], capture_output=True, text=True, timeout=120)
        assert done.returncode == 0, done.stderr

    def content(path):
        with AnyReader([path]) as reader:
            return ({c.topic: c.msgtype for c in reader.connections},
                    [(c.topic, t, repr(reader.deserialize(raw, c.msgtype))) for c, t, raw in reader.messages()])
    original, converted = content(bag), content(back)
    assert converted == original
    assert len(original[1]) == 2 * N + 1


def test_a_file_name_ending_in_mcap_gives_a_bare_mcap_and_a_used_folder_is_refused(context, tmp_path):
    from itasc_bringup.recording import Recorder
    from itasc_bringup.recording.bag import BagExists

    path = tmp_path / 'run.mcap'
    _record(context, path)
    assert sorted(p.name for p in tmp_path.iterdir()) == ['run.mcap']
    from rosbags.highlevel import AnyReader
    with AnyReader([path]) as reader:
        assert sum(1 for _ in reader.messages()) == 2 * N + 1

    used = tmp_path / 'used'
    used.mkdir()
    (used / 'notes.txt').write_text('mine')
    with pytest.raises(BagExists, match='used exists already'):
        Recorder(used, context=context)
