"""The workspace built by `make setup` is a working ROS 2 install of our packages."""
import os

import pytest


def test_ament_index_has_itasc_bringup():
    from ament_index_python.packages import get_package_prefix, get_resource

    content, prefix = get_resource('packages', 'itasc_bringup')
    assert os.path.isdir(prefix)
    assert get_package_prefix('itasc_bringup') == prefix


@pytest.mark.parametrize('package', ['itasc_msgs', 'itasc_core', 'itasc_tasks', 'itasc_drivers'])
def test_ament_index_has_package(package):
    from ament_index_python.packages import get_package_share_directory

    assert os.path.isfile(os.path.join(get_package_share_directory(package), 'package.xml'))


@pytest.mark.parametrize('executable', ['bootstrap', 'itasc-plot', 'itasc-graph', 'itasc-foxglove'])
def test_bringup_executables_installed(repo_root, executable):
    path = repo_root / 'install' / 'itasc_bringup' / 'lib' / 'itasc_bringup' / executable
    assert path.is_file(), f'{path} missing: run make setup'
    assert os.access(path, os.X_OK), f'{path} is not executable'


def test_event_message_roundtrip():
    from itasc_msgs.msg import Event
    from rclpy.serialization import deserialize_message, serialize_message

    event = Event(source='/app/itasc/coordinator', name='e_ApproachObject_configured',
                  seq=42, priority=True, detail='ok')
    event.stamp.sec = 7
    event.stamp.nanosec = 123
    data = serialize_message(event)
    assert isinstance(data, bytes) and len(data) > 0
    back = deserialize_message(data, Event)
    assert back == event


def test_bringup_share_has_config(repo_root):
    from ament_index_python.packages import get_package_share_directory

    share = get_package_share_directory('itasc_bringup')
    assert os.path.isdir(os.path.join(share, 'config'))
    # every file of the repo's config/ tree is installed
    config = repo_root / 'config'
    for path in config.rglob('*'):
        if path.is_file() and '__pycache__' not in path.parts and not path.name.startswith('.'):
            rel = path.relative_to(config)
            assert os.path.exists(os.path.join(share, 'config', rel)), f'{rel} not installed; run make setup'
