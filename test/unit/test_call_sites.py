"""The call sites of log calls (itasc_core.communication.call_sites): found from the frame alone, never
with ``inspect`` (which reads source files, 60 ms for a process's first log call), and the same
for rclpy's filters as rclpy's own."""

from __future__ import annotations

import inspect
import os
import sys

import pytest
import rclpy.logging

from itasc_core.communication import call_sites
from itasc_core.entity import CompositeContext, Entity


@pytest.fixture
def entity_logger():
    """The logger of an entity (which installs the call sites), rclpy initialised for it."""
    rclpy.init()
    entity = Entity('speaker', composite=CompositeContext(name='app', namespace='/app'))
    try:
        yield entity.get_logger()
    finally:
        entity.destroy_node()
        rclpy.try_shutdown()


def _no_inspect(*args, **kwargs):
    raise AssertionError('a log call read the caller through inspect')


def test_an_entity_logs_without_inspecting_its_caller(entity_logger, monkeypatch):
    monkeypatch.setattr(inspect, 'getframeinfo', _no_inspect)
    monkeypatch.setattr(inspect, 'currentframe', _no_inspect)
    assert entity_logger.warning('the rows are late', throttle_duration_sec=1.0)


def test_the_call_site_is_the_callers_line_as_rclpy_finds_it(entity_logger):
    def warn():
        entity_logger.warning('late', throttle_duration_sec=5.0)
        return sys._getframe()

    frame = warn()
    site, = [site for site in entity_logger.contexts if site.function_name == 'warn']
    assert site.file_path == __file__
    assert site.line_number == frame.f_code.co_firstlineno + 1
    # rclpy's four values for one frame (rcutils_logger.CallerId, its file through inspect)
    assert call_sites.CallerId(frame) == (frame.f_code.co_name, os.path.abspath(inspect.getframeinfo(frame).filename),
                                          frame.f_lineno, frame.f_lasti)


def test_rclpy_filters_keep_their_state_per_call_site(entity_logger):
    first = [entity_logger.info('once here', once=True) for _ in range(3)]
    second = [entity_logger.info('once there', once=True) for _ in range(3)]
    throttled = [entity_logger.info('throttled', throttle_duration_sec=60.0) for _ in range(3)]
    assert first == second == throttled == [True, False, False]


def test_every_logger_of_the_process_finds_its_call_site_the_same_way(entity_logger, monkeypatch):
    monkeypatch.setattr(inspect, 'getframeinfo', _no_inspect)
    assert rclpy.logging.get_logger('bootstrap_console').info('a line of the console')
