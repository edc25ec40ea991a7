"""The recorder's CDR encoder (issue #9): the bytes it writes for a sample decode, with rclpy (Fast
CDR, what ROS tools use) and with rosbags (what itasc-plot and the tests read recordings with), to
the message the sample stands for, for every data-flow message type and the empty sequences whose
alignment Fast CDR handles its own way."""

import itertools

import numpy as np
import pytest
from rclpy.serialization import deserialize_message
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from itasc_core.communication import cdr
from itasc_core.communication.cdr import encoder
from itasc_bringup.recording.definitions import definition
from itasc_core.communication.samples import Float64Sample, JointSample, as_message
from itasc_core.itasc.entities.messages import (ControlSample, FeaturesSample, RowsSample, SetpointSample,
                                                SolverStatusSample, TaskStateSample)

J = tuple(f'panda_joint{i}' for i in range(1, 8))
SAMPLES = [
    Float64Sample(0.25),
    FeaturesSample(1.5, ('x', 'y', 'z', 'rx', 'ry', 'rz'), J, np.arange(6.0), np.arange(42.0).reshape(6, 7), 3),
    FeaturesSample(1.5, ('distance',), J, np.arange(1.0), np.arange(7.0).reshape(1, 7), None),
    FeaturesSample(1.5, (), (), np.zeros(0), np.zeros((0, 0)), None),
    SetpointSample(2.0, ('x', 'y'), np.array([1.0, 2.0]), np.zeros(2)),
    ControlSample(2.0, ('d',), desired=np.zeros(1), lower=np.array([-np.inf]), upper=np.array([np.inf]),
                  setpoint=np.ones(1), error=np.ones(1)),
    RowsSample(2.0, 'Approach', priority=1, inequality=False, joint_names=J, jacobian=np.ones((6, 7)),
               desired=np.ones(6), lower=np.ones(6), upper=np.ones(6), weights=np.ones(6)),
    RowsSample(2.0, 'Empty', priority=0, inequality=True, joint_names=J, jacobian=np.ones((0, 7)),
               desired=np.ones(0), lower=np.ones(0), upper=np.ones(0), weights=np.ones(0)),
    TaskStateSample(3.25, 'Avoid', output=np.ones(1), setpoint=np.ones(1), error=np.zeros(1), error_norm=0.5),
    SolverStatusSample(4.0, 'Solver', status='ok', solve_time=1e-4, min_singular_value=-1.0, damping=0.0,
                       active_tasks=('A', 'Bc')),
    *(JointSample(1700000000.123456, names, np.arange(p, dtype=float), velocity=np.ones(v), effort=np.ones(e))
      for names in (J, ('a',), ('abc',), ()) for p, v, e in itertools.product([0, 1, 2], repeat=3)),
]


def _type_name(msg) -> str:
    return f"{type(msg).__module__.split('.')[0]}/msg/{type(msg).__name__}"


@pytest.fixture(scope='module')
def store():
    store = get_typestore(Stores.ROS2_JAZZY)
    for name in ('Features', 'Setpoint', 'Control', 'ConstraintRows', 'TaskState', 'SolverStatus'):
        _, text = definition(f'itasc_msgs/msg/{name}')
        store.register(get_types_from_msg(text.split('\n====')[0], f'itasc_msgs/msg/{name}'))
    return store


@pytest.mark.parametrize('sample', SAMPLES, ids=lambda s: type(s).__name__)
def test_a_samples_cdr_bytes_decode_to_its_message(sample, store):
    msg = as_message(sample)
    data = encoder(type(sample))(sample)
    assert deserialize_message(data, type(msg)) == msg
    assert encoder(type(msg))(msg) == data  # a message itself is encoded the same
    decoded = store.deserialize_cdr(data, _type_name(msg))
    for field in type(msg).get_fields_and_field_types():
        ours, theirs = getattr(msg, field), getattr(decoded, field)
        if field in ('stamp', 'header'):
            stamp = ours.stamp if field == 'header' else ours
            other = theirs.stamp if field == 'header' else theirs
            assert (other.sec, other.nanosec) == (stamp.sec, stamp.nanosec)
        elif isinstance(ours, str):
            assert theirs == ours
        else:
            assert np.array_equal(np.asarray(theirs), np.asarray(ours)), field


def test_an_encoder_follows_its_samples_when_their_names_and_sizes_change():
    """The encoder keeps a template per shape (strings and name lists, sizes): a new name list of
    the same size, a new size, and more shapes than it keeps each decode to their own message."""
    encode = encoder(SetpointSample)
    for k in range(200):
        names = (f'x{k}', f'y{k}', f'z{k}') if k < 100 else tuple(f'n{k}_{i}' for i in range(k % 7))
        sample = SetpointSample(k * 0.5, names, np.arange(len(names), dtype=float), np.full(len(names), k))
        assert deserialize_message(encode(sample), type(as_message(sample))) == as_message(sample), k


def test_an_encoder_makes_one_template_for_the_same_names_in_a_new_tuple_each_message(monkeypatch):
    """A Solver writes its active tasks as a new tuple every tick: the same names are the same
    shape, so its messages are packed with the template made for the first (each template cost
    ~30 us, most of the recorder's time per tick at 1 kHz)."""
    made, original = [], cdr._template

    def template(*args):
        made.append(args)
        return original(*args)
    monkeypatch.setattr(cdr, '_template', template)
    encode = cdr._compile(SolverStatusSample)  # an encoder of its own, made with the counting template
    for k in range(50):
        tasks = tuple(f'{name}' for name in ('Approach', 'Avoid'))
        sample = SolverStatusSample(k * 0.001, 'Solver', status='ok', solve_time=1e-4, min_singular_value=0.5,
                                    damping=0.0, active_tasks=tasks if k < 40 else tasks[:1])
        assert deserialize_message(encode(sample), type(as_message(sample))) == as_message(sample), k
    assert len(made) == 2  # two shapes: both tasks, then one


@pytest.mark.parametrize('sample', SAMPLES, ids=lambda s: type(s).__name__)
def test_the_cdr_bytes_of_a_message_decode_to_its_sample(sample):
    """What an input port fed over DDS hands its entity: the sample of the message, decoded from
    the bytes Fast DDS wrote (rclpy's serialiser) and from ours, twice (the second time the name
    lists come from the last message), with arrays that can be written to as rclpy's can."""
    from rclpy.serialization import serialize_message

    from itasc_core.communication.cdr import sample_decoder

    msg = as_message(sample)
    decode = sample_decoder(type(msg))
    for data in (serialize_message(msg), encoder(type(sample))(sample), serialize_message(msg)):
        decoded = decode(data)
        assert type(decoded) is type(sample)
        assert as_message(decoded) == msg
        for value in (getattr(decoded, slot) for slot in type(decoded).__slots__):
            if isinstance(value, np.ndarray) and value.size:
                value.flat[0] = value.flat[0]  # writable


def test_a_decoder_follows_the_names_when_they_change_and_refuses_bytes_that_are_no_message():
    from rclpy.serialization import serialize_message

    from itasc_core.communication.cdr import sample_decoder
    from sensor_msgs.msg import JointState

    decode = sample_decoder(JointState)
    for names in (J, J, ('a', 'b'), J[:6] + ('panda_jointX',), ()):
        sample = JointSample(2.5, names, np.arange(len(names), dtype=float))
        assert decode(serialize_message(as_message(sample))).name == names
    data = serialize_message(as_message(JointSample(2.5, J, np.arange(7.0))))
    with pytest.raises(ValueError, match='not the CDR of a JointState'):
        decode(data[:40])


def test_types_without_a_sample_class_have_no_decoder():
    from std_msgs.msg import String

    from itasc_core.communication.cdr import sample_decoder
    assert sample_decoder(String) is None
