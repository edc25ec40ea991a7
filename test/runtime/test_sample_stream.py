"""A composite process's stream of its outputs to the recording's writer process
(``itasc_core.communication.sample_stream``, ``--deploy per-composite --record``), read here from a
socket of the test's own."""
import os
import pickle
import secrets
import socket
import time

import numpy as np
import rclpy
from rclpy.serialization import deserialize_message

from itasc_core.communication.ports import LocalBus, OutputPort, PortSpec
from itasc_core.communication.sample_stream import (FRAME, MESSAGES, RECORD, SEND_PERIOD, TOPIC, SampleStream,
                                                    abstract_address)
from itasc_core.itasc.entities.messages import FeaturesSample
from itasc_msgs.msg import Features


def _frames(connection: socket.socket) -> list[tuple[int, bytes]]:
    """The whole frames the connection holds now."""
    data = b''
    try:
        while chunk := connection.recv(1 << 16, socket.MSG_DONTWAIT):
            data += chunk
    except BlockingIOError:
        pass
    frames, offset = [], 0
    while offset < len(data):
        kind, size = FRAME.unpack_from(data, offset)
        frames.append((kind, data[offset + FRAME.size:offset + FRAME.size + size]))
        offset += FRAME.size + size
    return frames


def _records(payload: bytes) -> list[tuple[int, bytes]]:
    records, offset = [], 0
    while offset < len(payload):
        key, _, _, size = RECORD.unpack_from(payload, offset)
        records.append((key, payload[offset + RECORD.size:offset + RECORD.size + size]))
        offset += RECORD.size + size
    return records


def _features(k: int) -> FeaturesSample:
    return FeaturesSample(k * 0.01, ('distance',), ('j1',), np.array([0.1 * k]), np.array([[1.0]]))


def test_a_stream_announces_each_output_at_once_and_sends_its_samples_within_the_send_period(context):
    """Each output under the prefix is announced when it appears (the recorder then reads it over no
    DDS), and what was tapped reaches the writer within :data:`SEND_PERIOD` however little it is:
    a stream that waited for a full batch held a slow composite's samples for seconds, lost if its
    process was killed, and missing from the writer's flushes that ``mcap recover`` salvages."""
    name = f'itasc-test-{os.getpid()}-{secrets.token_hex(4)}'
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as listening:
        listening.bind(abstract_address(name))
        listening.listen(1)
        node = rclpy.create_node('task', context=context)
        broken = []
        stream = SampleStream(LocalBus.of(context), address=abstract_address(name), prefix='/app',
                              on_broken=lambda: broken.append(True))
        connection, _ = listening.accept()
        try:
            progress = OutputPort(node, PortSpec(name='progress', direction='output', msg_type=Features,
                                                 id='/app/task/progress'))
            OutputPort(node, PortSpec(name='x', direction='output', msg_type=Features, id='/elsewhere/x'))
            for k in range(3):
                progress.write(_features(k))
                stream.drain()
            frames = _frames(connection)
            assert [kind for kind, _ in frames] == [TOPIC]  # announced at once, the samples wait
            key, topic, type_name, profiles = pickle.loads(frames[0][1])
            assert (topic, type_name, profiles[0]['reliability']) == ('/app/task/progress', 'itasc_msgs/msg/Features',
                                                                     'reliable')
            time.sleep(SEND_PERIOD)
            stream.drain()
            frames = _frames(connection)
            assert [kind for kind, _ in frames] == [MESSAGES]
            records = _records(frames[0][1])
            assert [k for k, _ in records] == [key] * 3
            assert [deserialize_message(data, Features).value.tolist() for _, data in records] == [
                [0.0], [0.1], [0.2]]
            connection.close()  # the writer process is gone
            progress.write(_features(3))
            time.sleep(SEND_PERIOD)
            stream.drain()
            assert broken == [True]  # said once
            stream.drain()
            assert broken == [True]
        finally:
            stream.close()
            node.destroy_node()
