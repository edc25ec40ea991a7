"""``robot_description``: each robot's URDF as the application model loads it (paper §4.1 "Robots
and Objects": the Robot's kinematic model), for robot_state_publisher, RViz and Foxglove.

The URDF text with the model's joint-limit overrides written into its ``<limit>`` elements: the
limits the Solver and the simulated Driver use are the ones a viewer shows.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

from ..model.schema import Robot as RobotModel

__all__ = ['robot_description', 'link_tree']


def robot_description(robot: RobotModel) -> str:
    """The URDF XML of ``robot`` (its ``urdf`` an absolute path) with ``robot.limits`` applied."""
    root = ET.fromstring(Path(robot.urdf).read_text(encoding='utf-8'))
    joints = {j.get('name'): j for j in root.findall('joint')}  # not a <transmission>'s <joint>
    for name, override in robot.limits.items():
        joint = joints.get(name)
        if joint is None:
            continue  # a base coordinate (planar, free-flyer): not a URDF joint
        limit = joint.find('limit')
        if limit is None:
            limit = ET.SubElement(joint, 'limit', {'effort': '0'})
        for attribute, value in (('lower', override.lower), ('upper', override.upper),
                                 ('velocity', override.velocity)):
            if value is not None:
                limit.set(attribute, repr(float(value)))
    return ET.tostring(root, encoding='unicode', xml_declaration=True)


def link_tree(description: str) -> tuple[str, dict[str, tuple[str, bool]]]:
    """The root link of a URDF and, per other link, ``(parent link, joint is fixed)``."""
    root = ET.fromstring(description)
    parents = {j.find('child').get('link', ''): (j.find('parent').get('link', ''), j.get('type') == 'fixed')
               for j in root.findall('joint')}
    links = [link.get('name', '') for link in root.findall('link')]
    roots = [link for link in links if link not in parents]
    if len(roots) != 1:
        raise ValueError(f'URDF {root.get("name")!r} has {len(roots)} root links {roots}, expected one')
    return roots[0], parents
