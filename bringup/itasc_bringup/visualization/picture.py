"""The 3-D scene of a recorded run as PNG and GIF, without any viewer (issue #13): what RViz or
Foxglove would show, drawn with matplotlib from the recording's ``/tf_static``, ``/tf`` and markers
(paper §4.1 "Scene": robots, objects and their object frames; §2.2 the Tasks between them).

Robots are drawn as their TF links (parent to child link origins), the tool (the robot frame the
first Task moves, its ``o2``) as a blue dot; object frames as axes; the targets, the obstacles
with their size, each distance constraint with its ``d_min`` sphere, in the colour of its state.
One PNG per transition of the program's Running sub-FSM (``scene_<n>_<state>.png``), one at the
end (``scene_end.png``), and ``scene.gif``. The view holds everything the run shows at any time
(a mobile base driving off, a humanoid's head), the same for every picture.
"""

from __future__ import annotations

import pathlib
from bisect import bisect_left, bisect_right
from collections import defaultdict
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ['Drawn', 'render_scene', 'TOOL_COLOUR']

TOOL_COLOUR = '#0000ff'
TF, TF_STATIC, MARKERS, STATE = ('tf2_msgs/msg/TFMessage', 'tf2_msgs/msg/TFMessage',
                                 'visualization_msgs/msg/MarkerArray', 'itasc_msgs/msg/CoordinatorState')


@dataclass
class Drawn:
    """One picture: its file, the stamp of the markers it shows (a robot's joint state), where the
    tool was drawn (world coordinates and pixel coordinates in the PNG, origin top left)."""

    path: pathlib.Path
    stamp: tuple[int, int]
    tool: np.ndarray
    tool_pixel: tuple[float, float]


def _matrix(transform) -> np.ndarray:
    r, t = transform.rotation, transform.translation
    x, y, z, w = r.x, r.y, r.z, r.w
    m = np.eye(4)
    m[:3, :3] = [[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                 [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                 [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]]
    m[:3, 3] = t.x, t.y, t.z
    return m


def _pose_matrix(pose) -> np.ndarray:
    class _T:  # a Pose read as a Transform
        rotation, translation = pose.orientation, pose.position
    return _matrix(_T)


def _read(path: pathlib.Path) -> dict[str, list[tuple[int, Any]]]:
    from rosbags.highlevel import AnyReader

    out: dict[str, list] = defaultdict(list)
    with AnyReader([path]) as reader:
        for connection, stamp, raw in reader.messages():
            state = connection.msgtype == STATE and connection.topic.count('/') == 3
            if connection.msgtype in (TF, MARKERS) or state:
                out[connection.topic].append((stamp, reader.deserialize(raw, connection.msgtype)))
    return out


class _Tree:
    """TF edges over time: static ones, and the moving ones as TF looks them up (each frame's
    newest transform at or before a stamp: every robot's joint states have stamps of their own)."""

    def __init__(self, messages) -> None:
        self.static = {t.child_frame_id: (t.header.frame_id, _matrix(t.transform))
                       for _, m in messages.get('/tf_static', []) for t in m.transforms}
        moving: dict[str, list] = defaultdict(list)
        for _, m in messages.get('/tf', []):
            for t in m.transforms:
                moving[t.child_frame_id].append(((t.header.stamp.sec, t.header.stamp.nanosec), t.header.frame_id,
                                                 _matrix(t.transform)))
        self._moving = {child: sorted(entries, key=lambda e: e[0]) for child, entries in moving.items()}
        self._times = {child: [e[0] for e in entries] for child, entries in self._moving.items()}
        #: The stamps of moving transforms from which on every moving frame is known.
        first = max((times[0] for times in self._times.values()), default=None)
        self.stamps = {s for times in self._times.values() for s in times if first is not None and s >= first}

    def edges(self, stamp) -> dict:
        edges = dict(self.static)
        for child, entries in self._moving.items():
            _, parent, matrix = entries[max(bisect_right(self._times[child], stamp) - 1, 0)]
            edges[child] = (parent, matrix)
        return edges

    def world(self, frame: str, edges: dict) -> np.ndarray:
        m = np.eye(4)
        while frame != 'world':
            parent, edge = edges[frame]
            m, frame = edge @ m, parent
        return m


def _tool(tree: _Tree, markers) -> str:
    """The frame to mark: the first Task's ``o2`` (where its label is), else the frame deepest
    in the TF tree (the end of a kinematic chain)."""
    labels = [m.header.frame_id for m in markers if m.ns == 'tasks']
    if labels:
        return labels[0]
    edges = tree.edges(min(tree.stamps))

    def depth(frame: str) -> int:
        return 0 if frame == 'world' else 1 + depth(edges[frame][0])
    return max(edges, key=depth)


def _view(tree: _Tree, samples: list, *, margin: float = 0.1) -> tuple[np.ndarray, float]:
    """Centre and half width of a cube holding every frame and marker of ``samples`` (at most 50
    of them looked at)."""
    points = []
    for _, array, stamp in samples[::max(1, len(samples) // 50)] + samples[-1:]:
        edges = tree.edges(stamp)
        points += [tree.world(f, edges)[:3, 3] for f in edges]
        for marker in array.markers:
            centre = (tree.world(marker.header.frame_id, edges) @ _pose_matrix(marker.pose))[:3, 3]
            points += [centre - marker.scale.x / 2, centre + marker.scale.x / 2] if marker.type == 2 else [centre]
    low, high = np.min(points + [np.zeros(3)], axis=0), np.max(points + [np.zeros(3)], axis=0)
    return (low + high) / 2, float(np.max(high - low)) / 2 + margin


def _draw(ax, tree: _Tree, markers, stamp, *, tool: str, title: str,
          view: tuple[np.ndarray, float]) -> np.ndarray:
    from mpl_toolkits.mplot3d import proj3d  # noqa: F401  (registers the 3-D projection)

    edges = tree.edges(stamp)
    world = {f: tree.world(f, edges)[:3, 3] for f in edges}
    world['world'] = np.zeros(3)
    for child, (parent, _) in edges.items():  # the links (and object frames on their parents)
        if parent != 'world':
            ax.plot(*zip(world[parent], world[child]), color='0.35', linewidth=4, solid_capstyle='round')
    for marker in markers:
        frame = tree.world(marker.header.frame_id, edges) @ _pose_matrix(marker.pose)
        colour = (marker.color.r, marker.color.g, marker.color.b)
        if marker.type == 5:  # LINE_LIST
            points = [(frame @ [p.x, p.y, p.z, 1.0])[:3] for p in marker.points]
            colours = [(c.r, c.g, c.b) for c in marker.colors] or [colour] * len(points)
            for i in range(0, len(points) - 1, 2):
                ax.plot(*zip(points[i], points[i + 1]), color=colours[i], linewidth=2)
        elif marker.type == 2:  # SPHERE
            u, v = np.meshgrid(np.linspace(0, 2 * np.pi, 16), np.linspace(0, np.pi, 9))
            r = marker.scale.x / 2
            c = frame[:3, 3]
            ax.plot_wireframe(c[0] + r * np.cos(u) * np.sin(v), c[1] + r * np.sin(u) * np.sin(v),
                              c[2] + r * np.cos(v), color=colour, alpha=max(marker.color.a, 0.3), linewidth=0.6)
    # on top of everything, whatever its depth (a translucent target sphere around it would tint it)
    ax.computed_zorder = False
    ax.scatter(*world[tool], color=TOOL_COLOUR, s=60, depthshade=False, zorder=10)
    centre, half = view
    ax.set_xlim(centre[0] - half, centre[0] + half)
    ax.set_ylim(centre[1] - half, centre[1] + half)
    ax.set_zlim(centre[2] - half, centre[2] + half)
    ax.set_box_aspect((1, 1, 1))
    ax.set_xlabel('x [m]'), ax.set_ylabel('y [m]'), ax.set_zlabel('z [m]')
    ax.set_title(title)
    return world[tool]


def _pixel(fig, ax, point: np.ndarray) -> tuple[float, float]:
    from mpl_toolkits.mplot3d import proj3d
    x, y, _ = proj3d.proj_transform(*point, ax.get_proj())
    px, py = ax.transData.transform((x, y))
    return float(px), float(fig.bbox.height - py)


def render_scene(path: pathlib.Path, out: pathlib.Path, *, tool: str | None = None, gif: bool = True) -> list[Drawn]:
    """Write the scene pictures of the recording ``path`` into ``out``; return what was drawn."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    from matplotlib.animation import PillowWriter

    messages = _read(path)
    arrays = next((v for k, v in messages.items() if k.endswith('/markers')), [])
    if not arrays or '/tf_static' not in messages:
        return []
    tree = _Tree(messages)
    samples = [(t, a, (a.markers[0].header.stamp.sec, a.markers[0].header.stamp.nanosec))
               for t, a in arrays if a.markers]
    samples = [s for s in samples if s[2] in tree.stamps]
    if not samples:
        return []
    tool = tool or _tool(tree, samples[0][1].markers)
    view = _view(tree, samples)
    times = [t for t, _, _ in samples]
    program = next((v for k, v in messages.items() if k.endswith('/state')), [])
    moments, last = [], None
    for t, state in program:
        sub = state.state.removeprefix('Active.Run.Running').lstrip('.')
        if state.state.startswith('Active.Run.Running') and sub != last:
            moments.append((t, sub or 'Running'))
            last = sub
    moments = [(min(bisect_left(times, t), len(samples) - 1), name) for t, name in moments]
    moments.append((len(samples) - 1, 'end'))

    out.mkdir(parents=True, exist_ok=True)
    drawn = []
    for n, (index, name) in enumerate(moments):
        _, array, stamp = samples[index]
        fig = plt.figure(figsize=(6, 6), dpi=100)
        ax = fig.add_subplot(projection='3d')
        title = f'{name}  (t = {(times[index] - times[0]) * 1e-9:.2f} s)'
        point = _draw(ax, tree, array.markers, stamp, tool=tool, title=title, view=view)
        file = out / ('scene_end.png' if name == 'end' else f'scene_{n}_{name}.png')
        fig.canvas.draw()
        pixel = _pixel(fig, ax, point)
        fig.savefig(file)
        plt.close(fig)
        drawn.append(Drawn(file, stamp, point, pixel))
    if gif:
        fig = plt.figure(figsize=(5, 5), dpi=80)
        ax = fig.add_subplot(projection='3d')
        writer = PillowWriter(fps=10)
        with writer.saving(fig, str(out / 'scene.gif'), dpi=80):
            step = max(1, len(samples) // 150)
            for t, array, stamp in samples[::step]:
                ax.cla()
                _draw(ax, tree, array.markers, stamp, tool=tool, title=f't = {(t - times[0]) * 1e-9:.1f} s',
                      view=view)
                writer.grab_frame()
        plt.close(fig)
    return drawn
