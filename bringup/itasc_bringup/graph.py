"""``itasc-graph <app name | model path> [--out DIR]``: draw an application's composition.

Serves the paper's §3 (Fig. 1, the Composition Pattern) and §4.2 (Fig. 2, levels of composition)
and the SPEC's "Composition Pattern" section: every composite of the generic composition model
(:class:`itasc_core.composition.model.CompositeModel`) becomes a cluster, nested as the
composites are, holding its Coordinator, Composer, Configurator, Scheduler, Monitors and
Functional Entities, coloured as in the paper (Composer red, Coordinator blue, Scheduler yellow,
Monitor purple, Configurator green, Functional Entities white; deeper composites darker grey).

Edges: data flow as solid arrows labelled ``out_port -> in_port`` (a port of a child composite
is followed through its ``exports`` to the entity that owns it, and the arrow is clipped at the
child's box); a Monitor's watched port as a dashed arrow; events as double lines between each
entity and its Coordinator, and between a child's Coordinator and its parent's Coordinator.

Writes ``<name>_composition.{dot,svg,png}`` with graphviz's ``dot`` (``apt-get install graphviz``;
Python package ``graphviz``). Without ``dot`` only the ``.dot`` file is written.
"""

from __future__ import annotations

import argparse
import pathlib
import sys
from collections.abc import Sequence

from itasc_core.composition.model import CompositeModel, EntityModel

__all__ = ['KIND_COLOURS', 'build', 'draw', 'main']

#: (fill, font) per pattern role, after the paper's figures.
KIND_COLOURS = {
    'Coordinator': ('#3b6fd1', 'white'),
    'Composer': ('#d64541', 'white'),
    'Configurator': ('#3fa34d', 'white'),
    'Scheduler': ('#f2d43d', 'black'),
    'Monitor': ('#8e44ad', 'white'),
    'Entity': ('white', 'black'),
}
_ROLES = ('Coordinator', 'Composer', 'Configurator', 'Scheduler')
#: Event edges do not take part in ranking: the data flow alone lays the entities out.
_EVENT_EDGE = {'dir': 'none', 'color': '#3b6fd1:white:#3b6fd1', 'penwidth': '1.2',
               'constraint': 'false'}


def _cluster_fill(depth: int) -> str:
    level = max(0xa0, 0xf4 - 0x16 * depth)
    return f'#{level:02x}{level:02x}{level:02x}'


def _node_id(path: str, name: str) -> str:
    return f'{path}/{name}'


def _resolve(model: CompositeModel, path: str, end: str) -> tuple[str, str]:
    """The node that owns port ``entity.port`` of ``model``, following exports down; and the
    port's name at that node."""
    entity_name, port = end.split('.', 1)
    entity = model.entity(entity_name)
    if isinstance(entity, EntityModel):
        return _node_id(path, entity.name), port
    child_path = f'{path}/{entity.name}'
    inner = entity.exports.get(port)
    if inner is None or inner.split('.')[0] not in {e.name for e in entity.entities}:
        return _node_id(child_path, 'Coordinator'), port  # unknown export: the composite itself
    return _resolve(entity, child_path, inner)


def _entity_label(name: str, kind: str) -> str:
    return f'<<b>{name}</b><br/><font point-size="9">{kind}</font>>'


def _add_composite(graph, model: CompositeModel, path: str, depth: int,
                   parent_coordinator: str | None) -> None:
    with graph.subgraph(name=f'cluster_{path}') as c:
        c.attr(label=f'<<b>{model.name}</b>>', style='filled,rounded', color='#555555',
               fillcolor=_cluster_fill(depth), fontsize='14', labeljust='l')
        coordinator = _node_id(path, 'Coordinator')
        with c.subgraph() as roles:   # the pattern's roles in one row on top, Coordinator first
            roles.attr(rank='same')
            for role in _ROLES:
                fill, font = KIND_COLOURS[role]
                roles.node(_node_id(path, role), role, fillcolor=fill, fontcolor=font)
            for left, right in zip(_ROLES, _ROLES[1:]):
                roles.edge(_node_id(path, left), _node_id(path, right), style='invis')
        for role in _ROLES[1:]:
            c.edge(coordinator, _node_id(path, role), **_EVENT_EDGE)
        if parent_coordinator:
            graph.edge(parent_coordinator, coordinator, **_EVENT_EDGE)
        fill, font = KIND_COLOURS['Monitor']
        for monitor in model.monitors:
            node = _node_id(path, monitor.name)
            c.node(node, _entity_label(monitor.name, monitor.event), fillcolor=fill, fontcolor=font)
            c.edge(coordinator, node, **_EVENT_EDGE)
        fill, font = KIND_COLOURS['Entity']
        for entity in model.entities:
            if isinstance(entity, CompositeModel):
                _add_composite(c, entity, f'{path}/{entity.name}', depth + 1, coordinator)
            else:
                node = _node_id(path, entity.name)
                c.node(node, _entity_label(entity.name, entity.kind), fillcolor=fill,
                       fontcolor=font)
                c.edge(coordinator, node, **_EVENT_EDGE)


def _add_data_flow(graph, model: CompositeModel, path: str) -> None:
    for connection in model.connections:
        source, out_port = _resolve(model, path, connection.source)
        target, in_port = _resolve(model, path, connection.target)
        attrs = {}
        src_entity, dst_entity = connection.source.split('.')[0], connection.target.split('.')[0]
        if isinstance(model.entity(src_entity), CompositeModel):
            attrs['ltail'] = f'cluster_{path}/{src_entity}'
        if isinstance(model.entity(dst_entity), CompositeModel):
            attrs['lhead'] = f'cluster_{path}/{dst_entity}'
        label = f'{connection.source.split(".")[1]} → {connection.target.split(".")[1]}'
        # dot places a label at the middle of the unclipped edge: off the drawn arrow when it
        # is clipped at a composite's box, so those get an external label instead
        attrs['xlabel' if attrs else 'label'] = label
        graph.edge(source, target, penwidth='1.6', **attrs)
    for monitor in model.monitors:
        if monitor.watch.split('.')[0] in {e.name for e in model.entities}:
            source, port = _resolve(model, path, monitor.watch)
            graph.edge(source, _node_id(path, monitor.name), label=monitor.watch.split('.')[1],
                       style='dashed', color='#8e44ad', fontcolor='#8e44ad')
    for child in model.children:
        _add_data_flow(graph, child, f'{path}/{child.name}')


def build(model: CompositeModel):
    """The graphviz ``Digraph`` of ``model`` (not rendered)."""
    import graphviz

    graph = graphviz.Digraph(model.name, graph_attr={
        'compound': 'true', 'rankdir': 'TB', 'fontname': 'Helvetica', 'newrank': 'true',
        'nodesep': '0.25', 'ranksep': '0.5', 'label': f'Composition of {model.name}',
        'labelloc': 't', 'fontsize': '18',
    }, node_attr={'shape': 'box', 'style': 'filled,rounded', 'fontname': 'Helvetica',
                  'fontsize': '11'},
        edge_attr={'fontname': 'Helvetica', 'fontsize': '9'})
    _add_composite(graph, model, f'/{model.name}', 0, None)
    _add_data_flow(graph, model, f'/{model.name}')
    return graph


def draw(model: CompositeModel, out_dir: str | pathlib.Path) -> tuple[pathlib.Path, pathlib.Path]:
    """Write ``<name>_composition.{dot,svg,png}`` into ``out_dir``; return the SVG and PNG paths.

    Raises ``graphviz.ExecutableNotFound`` (after writing the .dot) when ``dot`` is missing.
    """
    out = pathlib.Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    graph = build(model)
    stem = out / f'{model.name}_composition'
    stem.with_suffix('.dot').write_text(graph.source)
    paths = []
    for fmt in ('svg', 'png'):
        path = stem.with_suffix('.' + fmt)
        path.write_bytes(graph.pipe(format=fmt))
        paths.append(path)
    return paths[0], paths[1]


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog='itasc-graph', description=__doc__.split('\n\n')[0])
    parser.add_argument('app', help='application name (config/apps/<name>.yaml) or model path')
    parser.add_argument('--out', type=pathlib.Path, default=pathlib.Path('out'),
                        help='output directory (default: ./out)')
    args = parser.parse_args(argv)
    import graphviz
    from itasc_core.composition.loader import ModelError

    from .apps import load_composition
    try:
        model = load_composition(args.app)
        svg, png = draw(model, args.out)
    except ModelError as err:
        print(f'itasc-graph: error: {err}', file=sys.stderr)
        return 2
    except graphviz.ExecutableNotFound:
        print(f"itasc-graph: graphviz 'dot' not found (apt-get install graphviz); wrote only "
              f'{args.out}/{model.name}_composition.dot', file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        return 130
    print(svg)
    print(png)
    return 0


if __name__ == '__main__':
    sys.exit(main())
