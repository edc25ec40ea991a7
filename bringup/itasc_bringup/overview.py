"""``itasc-plot``'s overview page (SPEC: recording the whole run): one HTML page showing every
picture of a recorded run, task meanings first, then joints, life cycle and the 3-D scene."""

from __future__ import annotations

import html
import pathlib

__all__ = ['write_overview']

ORDER = ('task_errors', 'joints_', 'lifecycle', 'scene')


def _rank(path: pathlib.Path) -> tuple[int, str]:
    return next((i for i, prefix in enumerate(ORDER) if path.name.startswith(prefix)), len(ORDER)), path.name


def write_overview(recording: pathlib.Path, pictures: list[pathlib.Path], out: pathlib.Path) -> pathlib.Path:
    """``out/index.html``: every picture, in reading order, linked relative to ``out``."""
    items = ''.join(
        f'<figure><figcaption>{html.escape(p.name)}</figcaption>'
        f'<a href="{html.escape(p.name)}"><img src="{html.escape(p.name)}" alt="{html.escape(p.stem)}"></a></figure>\n'
        for p in sorted(pictures, key=_rank))
    page = (f'<!doctype html>\n<html><head><meta charset="utf-8"><title>{html.escape(recording.name)}</title>'
            '<style>body{font-family:sans-serif;margin:1em}img{max-width:100%;border:1px solid #ccc}'
            'figure{margin:0 0 1.5em 0}figcaption{font-weight:bold;margin-bottom:.3em}</style></head>\n'
            f'<body><h1>Run {html.escape(str(recording))}</h1>\n{items}</body></html>\n')
    path = out / 'index.html'
    path.write_text(page, encoding='utf-8')
    return path
