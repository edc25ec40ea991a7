"""Unit tests of the plain-Python iTaSC math (no ROS): make the source packages importable
without an install, and share the robot models and a breakable copy of the shipped config/."""

import importlib.util
import pathlib
import shutil
import sys

import pytest

REPO = pathlib.Path(__file__).resolve().parents[2]
for package in ('itasc_core', 'itasc_tasks'):
    if importlib.util.find_spec(package) is None:  # not installed (no colcon overlay)
        sys.path.insert(0, str(REPO / 'src' / package))

PANDA = REPO / 'config' / 'robots' / 'panda.urdf'
PANDA_MOBILE = REPO / 'config' / 'robots' / 'panda_mobile.urdf'


@pytest.fixture
def panda():
    """A fixed-base Panda with an object frame 'ee' at the TCP."""
    from itasc_core.itasc import Robot
    robot = Robot('panda', PANDA)
    robot.add_frame('ee', 'panda_hand_tcp')
    return robot


@pytest.fixture
def config(tmp_path: pathlib.Path) -> pathlib.Path:
    """A copy of the shipped config/ to break."""
    shutil.copytree(REPO / 'config', tmp_path / 'config')
    return tmp_path / 'config'

