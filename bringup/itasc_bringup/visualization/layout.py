"""A Foxglove (or Lichtblick) layout for any application, made from its model (issue #13).

The layout's panels name the application's own topics: a 3-D panel (TF and the markers, followed
from ``world``, looking at the robots and objects), each Task's error (an equality Task's
``error_norm``, an inequality Task's constrained value), ``/diagnostics`` and the life cycle of the
root and the program. ``ros2 run itasc_bringup itasc-foxglove APP -o layout.json`` writes it;
``config/foxglove/approach_object.json`` is this module's for ``approach_object``.

    layout = foxglove_layout(load_application(path))
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from ..model.schema import Application

__all__ = ['foxglove_layout']

#: The camera's distance when the scene fits in it [m]; a wider scene moves it back.
CAMERA_DISTANCE = 2.2


def _view(app: Application) -> tuple[list[float], float]:
    """The centre of what there is to see (robot bases, objects) and a camera distance holding it."""
    points = [r.xyz for r in app.program.robots] + [o.xyz for o in app.program.objects]
    low = [min(p[i] for p in points) for i in range(3)]
    high = [max(p[i] for p in points) for i in range(3)]
    centre = [round((a + b) / 2, 3) for a, b in zip(low, high)]
    half_diagonal = math.dist(low, high) / 2
    return centre, round(max(CAMERA_DISTANCE, 3.0 * half_diagonal), 2)


def _path(value: str, label: str) -> dict[str, Any]:
    return {'value': value, 'enabled': True, 'timestampMethod': 'receiveTime', 'label': label}


def foxglove_layout(app: Application) -> dict[str, Any]:
    """Foxglove's layout data (panel configs by id, their mosaic) for ``app``."""
    root = f'/{app.name}'
    program = f'{root}/{app.program.name}'
    centre, distance = _view(app)
    errors = [_path(f'{program}/{t.name}/Rows/state.output[0]', f'{t.name} value') if t.constraint == 'inequality'
              else _path(f'{program}/{t.name}/Rows/state.error_norm', f'{t.name} error') for t in app.program.tasks]
    return {
        'configById': {
            '3D!itasc': {
                'cameraState': {'distance': distance, 'perspective': True, 'phi': 55, 'thetaOffset': 135,
                                'targetOffset': centre, 'target': [0, 0, 0], 'targetOrientation': [0, 0, 0, 1],
                                'fovy': 45, 'near': 0.01, 'far': 100},
                'followMode': 'follow-pose', 'followTf': 'world',
                'scene': {'transforms': {'showLabel': False, 'axisScale': 0.5, 'lineWidth': 2}},
                'transforms': {},
                'topics': {f'{root}/markers': {'visible': True}},
                'layers': {'grid': {'visible': True, 'frameLocked': True, 'label': 'Grid', 'instanceId': 'grid',
                                    'layerId': 'foxglove.Grid', 'size': 2, 'divisions': 20, 'lineWidth': 1,
                                    'color': '#248eff', 'position': [0, 0, 0], 'rotation': [0, 0, 0], 'order': 1}},
            },
            'Plot!errors': {'title': 'Task errors', 'paths': errors, 'showXAxisLabels': True,
                            'showYAxisLabels': True, 'showLegend': True, 'legendDisplay': 'floating',
                            'isSynced': True, 'xAxisVal': 'timestamp'},
            'DiagnosticSummary!health': {'minLevel': 0, 'pinnedIds': [], 'hardwareIdFilter': '',
                                         'topicToRender': '/diagnostics'},
            'StateTransitions!lifecycle': {'paths': [{'value': f'{ns}/state.state', 'timestampMethod': 'receiveTime'}
                                                     for ns in (root, program)], 'isSynced': True},
        },
        'globalVariables': {},
        'userNodes': {},
        'playbackConfig': {'speed': 1},
        'layout': {'direction': 'row', 'first': '3D!itasc',
                   'second': {'direction': 'column', 'first': 'Plot!errors',
                              'second': {'direction': 'column', 'first': 'DiagnosticSummary!health',
                                         'second': 'StateTransitions!lifecycle', 'splitPercentage': 50},
                              'splitPercentage': 40},
                   'splitPercentage': 62},
    }


def main(argv: list[str] | None = None) -> int:
    """``itasc-foxglove APP [-o FILE]``: the layout of an application (a shipped one's name or a
    model file), on standard output or into FILE."""
    from itasc_core.composition.loader import ModelError

    from ..apps import resolve_app
    from ..model import load_application
    from . import _is_application

    parser = argparse.ArgumentParser(prog='itasc-foxglove', description=main.__doc__)
    parser.add_argument('app', help='application name or model file')
    parser.add_argument('-o', '--output', type=Path, help='write the layout here instead of printing it')
    args = parser.parse_args(argv)
    try:
        path = resolve_app(args.app)
        if not _is_application(path):
            print(f'error: {path} is a composition model (composite:), not an application: it has no robots or '
                  f'Tasks to show', file=sys.stderr)
            return 2
        app = load_application(path)
    except (ModelError, OSError) as err:
        print(f'error: {err}', file=sys.stderr)
        return 2
    text = json.dumps(foxglove_layout(app), indent=2) + '\n'
    if args.output is None:
        sys.stdout.write(text)
    else:
        args.output.write_text(text, encoding='utf-8')
    return 0


if __name__ == '__main__':
    sys.exit(main())
