# PYTHON_ARGCOMPLETE_OK
"""``itasc-plot run.mcap [--out DIR] [--urdf robot.urdf]``: pictures of a recorded run.

Serves the SPEC's recording requirement ("recording the whole run to MCAP") and the paper's §6.1
(Coordinators publish their fully-qualified active state, so a recording can show it). Reads the
MCAP ROS 2 bag written by :mod:`itasc_bringup.recording` with rosbags' ``AnyReader``, which builds
every type, ours included, from the schemas stored in the file: no ROS install is needed.

Writes into ``DIR`` (default ``<stem>_plots/`` next to the file):

* ``task_errors.png`` - every ``itasc_msgs/msg/TaskState`` task: ``error_norm`` of all tasks on
  one axis, then per task its error components (grey where the task was inactive) or, for an
  inequality Task, its distance against ``d_min``/``d_max`` shaded where the bound was active
  (:mod:`itasc_bringup.task_plot`); every panel marks the Running sub-FSM transitions;
* ``joints_<topic>.png`` per ``sensor_msgs/msg/JointState`` topic - position and velocity of each
  joint. Limits are taken from the URDF given with ``--urdf`` (``<limit lower upper velocity>`` of
  each joint, matched by name) and drawn as dashed red lines; without ``--urdf`` no limits are
  drawn (a recording does not carry the robot model);
* ``lifecycle.png`` - one lane per composite (``itasc_msgs/msg/CoordinatorState``): a segment per
  state, coloured by its top-level state (Configure/Start/Run/Stop/Safety), labelled with the leaf
  state where it fits, and a tick per transition named by the event that caused it;
* ``scene_<n>_<state>.png``, ``scene_end.png``, ``scene.gif`` - the 3-D scene (robot links, object
  frames, targets, obstacles, distance constraints with ``d_min``) at each transition of the
  Running sub-FSM, at the end, and animated, when the run recorded TF and markers
  (:mod:`itasc_bringup.visualization.picture`);
* ``index.html`` - one overview page with all of them.

Time is the recording's receive time, in seconds from the first message.
"""

from __future__ import annotations

import argparse
import math
import pathlib
import re
import sys
import xml.etree.ElementTree as ET
from collections import defaultdict
from collections.abc import Sequence
from typing import Any

__all__ = ['main', 'plot_run', 'read_run', 'urdf_limits']

TOP_LEVEL_COLOURS = {
    'Configure': '#a6cee3', 'Start': '#b2df8a', 'Run': '#33a02c', 'Stop': '#fdbf6f',
    'Safety': '#e31a1c',
}
OTHER_COLOUR = '#d9d9d9'
TASK_STATE = 'itasc_msgs/msg/TaskState'
JOINT_STATE = 'sensor_msgs/msg/JointState'
COORDINATOR_STATE = 'itasc_msgs/msg/CoordinatorState'
CONSTRAINT_ROWS = 'itasc_msgs/msg/ConstraintRows'


class PlotError(Exception):
    """A user-facing error: printed without a traceback, exit status 2."""


Series = dict[str, list[tuple[float, Any]]]


def read_run(path: pathlib.Path) -> tuple[Series, dict[str, str], float]:
    """``({topic: [(t, msg), ...]}, {topic: type}, duration)`` for the topics we plot."""
    from rosbags.highlevel import AnyReader, AnyReaderError

    wanted = {TASK_STATE, JOINT_STATE, COORDINATOR_STATE, CONSTRAINT_ROWS}
    series: dict[str, list[tuple[float, Any]]] = defaultdict(list)
    try:
        with AnyReader([path]) as reader:
            start = reader.start_time if reader.message_count else 0
            duration = (reader.end_time - start) * 1e-9 if reader.message_count else 0.0
            connections = [c for c in reader.connections if c.msgtype in wanted]
            types = {c.topic: c.msgtype for c in connections}
            for connection, stamp, raw in reader.messages(connections=connections):
                series[connection.topic].append(
                    ((stamp - start) * 1e-9, reader.deserialize(raw, connection.msgtype)))
    except (AnyReaderError, OSError, ValueError, KeyError, AssertionError) as err:
        raise PlotError(f'cannot read {path}: {err or type(err).__name__}') from None
    return dict(series), types, duration


def urdf_limits(path: pathlib.Path) -> dict[str, tuple[float, float, float]]:
    """``{joint: (lower, upper, velocity)}`` from a URDF's ``<limit>`` tags (NaN if absent;
    continuous joints have no position limits)."""
    try:
        root = ET.parse(path).getroot()
    except (OSError, ET.ParseError) as err:
        raise PlotError(f'cannot read URDF {path}: {err}') from None
    limits: dict[str, tuple[float, float, float]] = {}
    for joint in root.findall('joint'):  # the robot's own, not a <transmission>'s
        limit = joint.find('limit')
        if limit is None or joint.get('type') == 'fixed':
            continue
        continuous = joint.get('type') == 'continuous'
        get = lambda key, limit=limit: float(limit.get(key, 'nan'))  # noqa: E731
        limits[joint.get('name', '')] = (math.nan if continuous else get('lower'),
                                     math.nan if continuous else get('upper'), get('velocity'))
    return limits


def _slug(topic: str) -> str:
    return re.sub(r'[^A-Za-z0-9]+', '_', topic).strip('_') or 'root'


def _matrix(rows: list[Sequence[float]]):
    import numpy as np

    width = max((len(r) for r in rows), default=0)
    out = np.full((len(rows), width), np.nan)
    for i, row in enumerate(rows):
        out[i, :len(row)] = row
    return out


def plot_task_errors(series: dict, types: dict, out: pathlib.Path) -> pathlib.Path | None:
    import matplotlib.pyplot as plt
    import numpy as np

    from .task_plot import draw_marks, inequality_traces, sub_fsm_marks

    tasks: dict[str, list[tuple[float, Any]]] = defaultdict(list)
    for topic, items in series.items():
        if types[topic] == TASK_STATE:
            for t, msg in items:
                tasks[msg.task or topic].append((t, msg))
    if not tasks:
        return None
    inequalities = {trace.task: trace for trace in inequality_traces(series, types)}
    marks = sub_fsm_marks(series, types)
    fig, axes = plt.subplots(len(tasks) + 1, 1, sharex=True, squeeze=False,
                             figsize=(10, 2.4 * (len(tasks) + 1) + 0.4))
    axes = axes[:, 0]
    for name, items in sorted(tasks.items()):
        if name not in inequalities:  # an inequality's error is 0 while its bound holds
            t = np.array([x[0] for x in items])
            axes[0].plot(t, [x[1].error_norm for x in items], label=name)
    axes[0].set_ylabel('‖error‖')
    axes[0].set_title('Task errors; distances against their bounds (dotted: Running sub-FSM transitions)', pad=14)
    axes[0].legend(loc='upper right', fontsize='small')
    draw_marks(axes[0], marks)
    for ax, (name, items) in zip(axes[1:], sorted(tasks.items())):
        if name in inequalities:
            _plot_inequality(ax, inequalities[name])
        else:
            _plot_error_components(ax, items)
        ax.set_ylabel(name)
        draw_marks(ax, marks, label=False)
    axes[-1].set_xlabel('time [s]')
    fig.tight_layout()
    path = out / 'task_errors.png'
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _plot_error_components(ax, items: list) -> None:
    import numpy as np

    t = np.array([x[0] for x in items])
    error = _matrix([x[1].error for x in items])
    for k in range(error.shape[1]):
        ax.plot(t, error[:, k], label=f'e[{k}]', linewidth=1)
    inactive = np.array([not x[1].active for x in items])
    if inactive.any():
        ax.fill_between(t, 0, 1, where=inactive, transform=ax.get_xaxis_transform(),
                        color='0.85', step='post', label='inactive')
    if error.shape[1]:
        ax.legend(loc='upper right', fontsize='x-small', ncol=min(6, error.shape[1] + 1))


def _plot_inequality(ax, trace) -> None:
    """The distance, its bounds, and where a bound was active (the Solver's motion on it)."""
    ax.plot(trace.t, trace.distance, color='tab:blue', linewidth=1.2, label='distance [m]')
    for value, name in ((trace.d_min, 'd_min'), (trace.d_max, 'd_max')):
        if value is not None:
            ax.axhline(value, color='tab:red', linestyle='--', linewidth=1.0, label=f'{name} {value:.4g}')
    if trace.active.any():
        ax.fill_between(trace.t, 0, 1, where=trace.active, transform=ax.get_xaxis_transform(),
                        color='tab:orange', alpha=0.3, step='post', label='bound active')
    ax.legend(loc='upper right', fontsize='x-small', ncol=4)


def plot_joints(topic: str, items: list, limits: dict, out: pathlib.Path) -> pathlib.Path:
    import matplotlib.pyplot as plt
    import numpy as np

    names: list[str] = []
    for _, msg in items:
        names.extend(n for n in msg.name if n not in names)
    t = np.array([x[0] for x in items])
    pos = np.full((len(items), len(names)), np.nan)
    vel = np.full((len(items), len(names)), np.nan)
    for i, (_, msg) in enumerate(items):
        for j, name in enumerate(msg.name):
            k = names.index(name)
            if j < len(msg.position):
                pos[i, k] = msg.position[j]
            if j < len(msg.velocity):
                vel[i, k] = msg.velocity[j]
    rows = max(1, len(names))
    fig, axes = plt.subplots(rows, 2, sharex=True, squeeze=False, figsize=(11, 1.7 * rows + 1))
    for k, name in enumerate(names):
        lower, upper, vmax = limits.get(name, (math.nan,) * 3)
        for ax, values, bounds in ((axes[k, 0], pos[:, k], (lower, upper)),
                                   (axes[k, 1], vel[:, k], (-vmax, vmax))):
            ax.plot(t, values, linewidth=1.2)
            for bound in bounds:
                if math.isfinite(bound):
                    ax.axhline(bound, color='tab:red', linestyle='--', linewidth=0.9)
            ax.grid(True, alpha=0.3)
        axes[k, 0].set_ylabel(name, rotation=0, ha='right', va='center')
    axes[0, 0].set_title('position [rad | m]')
    axes[0, 1].set_title('velocity [rad/s | m/s]')
    for ax in axes[-1]:
        ax.set_xlabel('time [s]')
    note = 'limits from URDF (dashed)' if limits else 'no limits (pass --urdf)'
    fig.suptitle(f'{topic}  -  {note}')
    fig.tight_layout()
    path = out / f'joints_{_slug(topic)}.png'
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _top_and_leaf(state: str) -> tuple[str, str]:
    parts = [p for p in state.split('.') if p]
    if not parts:
        return '', ''
    top = parts[1] if parts[0] == 'Active' and len(parts) > 1 else parts[0]
    return top, parts[-1]


def plot_lifecycle(series: dict, types: dict, duration: float,
                   out: pathlib.Path) -> pathlib.Path | None:
    import matplotlib.pyplot as plt
    from matplotlib.patches import Patch

    lanes = sorted((t for t in series if types[t] == COORDINATOR_STATE),
                   key=lambda t: (t.count('/'), t))
    if not lanes:
        return None
    fig, ax = plt.subplots(figsize=(12, 1.6 + 1.3 * len(lanes)))
    end = max(duration, max(series[t][-1][0] for t in lanes)) or 1.0
    ax.set_xlim(0, end * 1.01)
    ax.set_ylim(len(lanes) - 0.6, -0.95)   # inverted: first lane on top, room for event names
    renderer = fig.canvas.get_renderer()  # type: ignore[attr-defined]  # the Agg canvas has it
    labels = []
    for lane, topic in enumerate(lanes):
        items = series[topic]
        labels.append(items[-1][1].composite or topic)
        last_label_x = -math.inf
        for i, (t, msg) in enumerate(items):
            t_next = items[i + 1][0] if i + 1 < len(items) else end
            top, leaf = _top_and_leaf(msg.state)
            ax.barh(lane, t_next - t, left=t, height=0.45, edgecolor='white', linewidth=0.5,
                    color=TOP_LEVEL_COLOURS.get(top, OTHER_COLOUR))
            text = ax.text((t + t_next) / 2, lane, leaf, ha='center', va='center', fontsize=7)
            box = text.get_window_extent(renderer)
            x0, x1 = ax.transData.transform([(t, 0), (t_next, 0)])[:, 0]
            if box.width > (x1 - x0) - 2:
                text.remove()
            ax.plot([t, t], [lane - 0.3, lane + 0.25], color='black', linewidth=0.8)
            if msg.event:
                x = ax.transData.transform((t, 0))[0]
                if x - last_label_x > 14:   # else the tick alone marks the transition
                    name = msg.event if len(msg.event) <= 30 else msg.event[:29] + '…'
                    ax.text(t, lane - 0.3, name, rotation=35, fontsize=6.5, ha='left',
                            va='bottom', color='0.15', rotation_mode='anchor')
                    last_label_x = x
    ax.set_yticks(range(len(lanes)), labels)
    ax.set_xlabel('time [s]')
    ax.set_title('Life cycle of every composite (ticks: transitions, named by their event)')
    ax.legend(handles=[Patch(color=c, label=s) for s, c in TOP_LEVEL_COLOURS.items()],
              loc='upper center', bbox_to_anchor=(0.5, -0.5 / (len(lanes) + 1)), ncol=5,
              fontsize='small', frameon=False)
    fig.tight_layout()
    path = out / 'lifecycle.png'
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def plot_run(path: pathlib.Path, out: pathlib.Path,
             urdf: pathlib.Path | None = None) -> list[pathlib.Path]:
    """Write every picture the recording allows; return their paths."""
    import matplotlib
    matplotlib.use('Agg')

    limits = urdf_limits(urdf) if urdf else {}
    series, types, duration = read_run(path)
    out.mkdir(parents=True, exist_ok=True)
    written = [plot_task_errors(series, types, out)]
    written += [plot_joints(topic, items, limits, out)
                for topic, items in sorted(series.items()) if types[topic] == JOINT_STATE]
    written.append(plot_lifecycle(series, types, duration, out))
    from .visualization.picture import render_scene  # the 3-D scene, when the run recorded TF and markers
    scene = render_scene(path, out)
    written += [d.path for d in scene] + ([out / 'scene.gif'] if scene else [])
    done = [p for p in written if p is not None]
    if done:
        from .overview import write_overview
        done.append(write_overview(path, done, out))
    return done


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog='itasc-plot', description=__doc__.split('\n\n')[0])
    parser.add_argument('mcap', type=pathlib.Path, help='recorded run (MCAP ROS 2 bag)')
    parser.add_argument('--out', type=pathlib.Path, help='output directory '
                        '(default: <mcap stem>_plots/ next to the file)')
    parser.add_argument('--urdf', type=pathlib.Path, help='robot URDF for joint limit lines')
    import argcomplete
    argcomplete.autocomplete(parser)
    args = parser.parse_args(argv)
    out = args.out or args.mcap.with_name(args.mcap.stem + '_plots')
    try:
        if not args.mcap.exists():
            raise PlotError(f'{args.mcap}: no such file')
        written = plot_run(args.mcap, out, urdf=args.urdf)
    except PlotError as err:
        print(f'itasc-plot: error: {err}', file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130
    if not written:
        print(f'itasc-plot: {args.mcap} has no {TASK_STATE}, {JOINT_STATE} or '
              f'{COORDINATOR_STATE} messages; nothing to plot', file=sys.stderr)
        return 1
    for path in written:
        print(path)
    return 0


if __name__ == '__main__':
    sys.exit(main())
