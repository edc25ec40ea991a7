"""A robot's URDF as the viewers get it (itasc_bringup.visualization.description, paper §4.1
"Robots and Objects"): its link tree and the model's limit overrides, read from the URDF's own
``<joint>`` and ``<link>`` elements. A ``<transmission>`` (ros_control's, as in the UR and many
vendor URDFs) holds ``<joint name=...>`` elements of its own, without parent or child."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET

from itasc_bringup.model.schema import JointLimits, Robot
from itasc_bringup.plot import urdf_limits
from itasc_bringup.visualization.description import link_tree, robot_description

URDF = """<?xml version="1.0"?>
<robot name="arm">
  <link name="world"/>
  <link name="base"/>
  <link name="tool"/>
  <joint name="fix" type="fixed"><parent link="world"/><child link="base"/></joint>
  <joint name="shoulder" type="revolute">
    <parent link="base"/><child link="tool"/><axis xyz="0 0 1"/>
    <limit lower="-3.0" upper="3.0" velocity="2.0" effort="10"/>
  </joint>
  <transmission name="shoulder_trans">
    <type>transmission_interface/SimpleTransmission</type>
    <joint name="shoulder"><hardwareInterface>hardware_interface/VelocityJointInterface</hardwareInterface></joint>
    <actuator name="shoulder_motor"><mechanicalReduction>1</mechanicalReduction></actuator>
  </transmission>
</robot>
"""


def test_the_link_tree_of_a_urdf_with_transmissions():
    assert link_tree(URDF) == ('world', {'base': ('world', True), 'tool': ('base', False)})


def test_a_limit_override_reaches_the_joint_not_its_transmission(tmp_path):
    path = tmp_path / 'arm.urdf'
    path.write_text(URDF, encoding='utf-8')
    robot = Robot(name='arm', urdf=str(path), limits={'shoulder': JointLimits(upper=1.5, velocity=0.5)})
    root = ET.fromstring(robot_description(robot))
    (limit,) = root.findall("joint[@name='shoulder']/limit")
    assert (float(limit.get('lower')), float(limit.get('upper')), float(limit.get('velocity'))) == (-3.0, 1.5, 0.5)
    assert root.find('transmission/joint/limit') is None


def test_the_plots_limits_come_from_the_joints(tmp_path):
    path = tmp_path / 'arm.urdf'
    path.write_text(URDF, encoding='utf-8')
    limits = urdf_limits(path)
    assert list(limits) == ['shoulder'] and limits['shoulder'] == (-3.0, 3.0, 2.0)
    assert not any(math.isnan(v) for v in limits['shoulder'])
