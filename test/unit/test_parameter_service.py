"""The Configurator's parameter services list ``<entity>.<parameter>`` names as rclpy lists a node's
own (``ros2 param list`` and ``dump`` send prefixes and a depth): the same names and prefixes for
every request, checked against a real rclpy node that holds the same names."""

from __future__ import annotations

import pytest
import rclpy
from rcl_interfaces.srv import ListParameters
from rclpy.signals import SignalHandlerOptions

from itasc_core.configuration.parameter_service import listed

NAMES = ['CC.kp', 'CC.kind', 'Rows.weights', 'SPG.pose.xyz', 'SPG.pose.rpy', 'SPG.duration', 'Scene.objects.box.xyz']
REQUESTS = [([], ListParameters.Request.DEPTH_RECURSIVE), ([], 1), ([], 2), ([], 3), (['CC'], 0), (['CC'], 1),
            (['SPG'], 1), (['SPG'], 2), (['SPG.pose'], 1), (['SPG', 'Rows'], 0), (['Scene.objects'], 1),
            (['C'], 0), (['SPG.pose.xyz'], 0), (['nothing'], 0)]


@pytest.fixture(scope='module')
def node():
    context = rclpy.Context()
    rclpy.init(context=context, signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node('listed_like_rclpy', context=context, start_parameter_services=False)
    for name in NAMES:
        node.declare_parameter(name, 0.0)
    yield node
    node.destroy_node()
    rclpy.try_shutdown(context=context)


@pytest.mark.parametrize(('prefixes', 'depth'), REQUESTS)
def test_names_are_listed_as_rclpy_lists_a_nodes_own(node, prefixes, depth):
    own = node.list_parameters(prefixes, depth)
    theirs = listed(NAMES, prefixes, depth)
    mine = [n for n in own.names if n in NAMES]  # the node's use_sim_time aside
    assert (theirs.names, sorted(theirs.prefixes)) == (mine, sorted(own.prefixes)), (prefixes, depth)
