"""The Tasks drawn in the Scene (paper §2.2: a Task is a relation between two object frames with a
desired output or bounds; §4.1 "Scene"), as ``visualization_msgs/MarkerArray`` for RViz/Foxglove.

* ``frames``: every object frame as axes (x red, y green, z blue);
* ``targets``: the target of every Cartesian Task (its setpoint's final pose or position in o1);
* ``obstacles``: every object with a ``size``, as a sphere of that diameter;
* ``distance``: every distance Task as a line between its o1 and o2, and ``d_min`` as a sphere of
  radius ``d_min`` about o1, both coloured by the constraint's state (:func:`distance_state`);
* ``tasks``: a text per Task: its name, its Running state, active or not, its error.

Every marker is stamped with the joint state the frames were computed from, so its frame exists
in TF at its stamp.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
import pinocchio as pin
from builtin_interfaces.msg import Time
from geometry_msgs.msg import Point, Pose
from itasc_core.itasc.robot import se3
from std_msgs.msg import ColorRGBA
from visualization_msgs.msg import Marker, MarkerArray

from ..model.schema import Application
from .frames import WORLD, FrameTree, quaternion_xyzw

__all__ = ['TaskView', 'distance_state', 'scene_markers', 'STATE_COLOURS', 'AXIS_LENGTH']

AXIS_LENGTH = 0.08
#: Margin within which an inequality counts as at its bound [m].
AT_BOUND = 0.005
STATE_COLOURS = {'inactive': (0.6, 0.6, 0.6), 'active': (0.1, 0.8, 0.2),
                 'at_bound': (1.0, 0.6, 0.0), 'violated': (0.9, 0.1, 0.1)}


@dataclass
class TaskView:
    """What is known of a Task at display time."""

    name: str
    running_state: str = '-'
    active: bool = False
    error_norm: float = float('nan')


def distance_state(distance: float, *, d_min: float | None, d_max: float | None, active: bool) -> str:
    """``inactive``, ``violated`` (beyond a bound), ``at_bound`` (within 5 mm of one) or ``active``."""
    if not active:
        return 'inactive'
    lower = -np.inf if d_min is None else d_min
    upper = np.inf if d_max is None else d_max
    if distance < lower - 1e-4 or distance > upper + 1e-4:
        return 'violated'
    if distance < lower + AT_BOUND or distance > upper - AT_BOUND:
        return 'at_bound'
    return 'active'


def _colour(rgb, alpha: float = 1.0) -> ColorRGBA:
    return ColorRGBA(r=float(rgb[0]), g=float(rgb[1]), b=float(rgb[2]), a=float(alpha))


def _pose(placement: pin.SE3) -> Pose:
    pose = Pose()
    pose.position.x, pose.position.y, pose.position.z = map(float, placement.translation)
    (pose.orientation.x, pose.orientation.y, pose.orientation.z,
     pose.orientation.w) = quaternion_xyzw(placement.rotation)
    return pose


def _point(p) -> Point:
    return Point(x=float(p[0]), y=float(p[1]), z=float(p[2]))


def _marker(ns: str, index: int, kind: int, frame: str, stamp: Time, **fields) -> Marker:
    marker = Marker(ns=ns, id=index, type=kind, action=Marker.ADD, **fields)
    marker.header.frame_id = frame
    marker.header.stamp = stamp
    if 'pose' not in fields:
        marker.pose.orientation.w = 1.0
    return marker


@functools.lru_cache(maxsize=64)
def _axes_lines(placement: tuple[float, ...], length: float) -> tuple[list[Point], list[ColorRGBA]]:
    """The points and colours of axes at ``placement`` (a pose's 12 numbers): made once, since
    most axes never move in their frame (building them was a quarter of a drawing's time); only
    read afterwards."""
    pose = pin.SE3(np.array(placement[3:]).reshape(3, 3), np.array(placement[:3]))
    points, colours = [], []
    for axis, rgb in enumerate(((1, 0, 0), (0, 1, 0), (0, 0, 1))):
        points += [_point(pose.translation), _point(pose.act(length * np.eye(3)[axis]))]
        colours += [_colour(rgb), _colour(rgb)]
    return points, colours


def _axes(ns: str, index: int, frame: str, stamp: Time, placement: pin.SE3 | None = None,
          length: float = AXIS_LENGTH) -> Marker:
    placement = pin.SE3.Identity() if placement is None else placement
    points, colours = _axes_lines((*placement.translation, *placement.rotation.flatten()), length)
    marker = _marker(ns, index, Marker.LINE_LIST, frame, stamp, points=points, colors=colours)
    marker.scale.x = length / 10
    return marker


def object_frames(app: Application) -> list[str]:
    """TF names of every object frame (on objects and on robots)."""
    names = [f'{r.name}/{f.name}' for r in app.program.robots for f in r.frames]
    for obj in app.program.objects:
        names += [obj.name] + [f'{obj.name}/{f.name}' for f in obj.frames]
    return names


def _target(task) -> pin.SE3 | None:
    setpoint = task.setpoint
    if setpoint is None:
        return None
    if setpoint.pose is not None:
        return se3(setpoint.pose.xyz, setpoint.pose.rpy)
    if setpoint.value is not None and list(task.outputs or ['x', 'y', 'z'])[:3] == ['x', 'y', 'z']:
        return se3(setpoint.value[:3])
    return None


def scene_markers(app: Application, tree: FrameTree, views: dict[str, TaskView], stamp: Time) -> MarkerArray:
    """Every marker of the application's Scene and Tasks at the frames' current poses."""
    out: list[Marker] = []
    known = [f for f in object_frames(app) if tree.frame_pose(f) is not None]
    out += [_axes('frames', i, frame, stamp) for i, frame in enumerate(known)]
    for i, obj in enumerate(o for o in app.program.objects if o.size and tree.frame_pose(o.name) is not None):
        marker = _marker('obstacles', i, Marker.SPHERE, obj.name, stamp, color=_colour((0.8, 0.2, 0.8), 0.8))
        marker.scale.x = marker.scale.y = marker.scale.z = float(obj.size or 0.0)
        out.append(marker)
    tasks = [t for t in app.program.tasks if t.kind.reads == 'relation' and tree.frame_pose(t.chain['o1']) is not None
             and tree.frame_pose(t.chain['o2']) is not None]
    for i, task in enumerate(t for t in tasks if t.kind.pose_setpoints and _target(t) is not None):
        target = _target(task)
        sphere = _marker('targets', i, Marker.SPHERE, task.chain['o1'], stamp, pose=_pose(target),
                         color=_colour((0.2, 0.5, 1.0), 0.6))
        sphere.scale.x = sphere.scale.y = sphere.scale.z = 0.02
        out += [sphere, _axes('target_axes', i, task.chain['o1'], stamp, target, length=AXIS_LENGTH / 2)]
    for i, task in enumerate(t for t in tasks if t.type == 'distance'):
        p1, p2 = tree.frame_pose(task.chain['o1']).translation, tree.frame_pose(task.chain['o2']).translation
        view = views.get(task.name, TaskView(task.name))
        d_min = task.d_min[0] if task.d_min else None
        d_max = task.d_max[0] if task.d_max else None
        state = distance_state(float(np.linalg.norm(p2 - p1)), d_min=d_min, d_max=d_max, active=view.active)
        line = _marker('distance', i, Marker.LINE_LIST, WORLD, stamp, color=_colour(STATE_COLOURS[state]),
                       text=state, points=[_point(p1), _point(p2)])
        line.scale.x = 0.005
        out.append(line)
        if d_min is not None:
            bound = _marker('d_min', i, Marker.SPHERE, task.chain['o1'], stamp,
                            color=_colour(STATE_COLOURS[state], 0.25), text=state)
            bound.scale.x = bound.scale.y = bound.scale.z = 2.0 * d_min
            out.append(bound)
    for i, task in enumerate(tasks):
        view = views.get(task.name, TaskView(task.name))
        text = (f'{task.name}: {view.running_state}, {"active" if view.active else "inactive"}, '
                f'error {view.error_norm:.4f}')
        label = _marker('tasks', i, Marker.TEXT_VIEW_FACING, task.chain['o2'], stamp, text=text,
                        color=_colour((1.0, 1.0, 1.0)))
        label.pose.position.z = 0.1 + 0.05 * i
        label.scale.z = 0.03
        out.append(label)
    return MarkerArray(markers=out)
