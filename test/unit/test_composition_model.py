"""The composition model and its loader: wrong models are named by file, path and expectation."""

from __future__ import annotations

import math

import pytest

from itasc_core.communication.ports import PortSpec, SemanticMismatch, check_connection
from itasc_core.composition.loader import ModelError, load_model
from itasc_core.composition.model import CompositeModel
from itasc_core.computation.conditions import CONDITIONS
from itasc_core.computation.monitor import read_field
from std_msgs.msg import Float64MultiArray


def write(tmp_path, name: str, text: str):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_pattern_demo_loads_with_includes(repo_root):
    model = load_model(CompositeModel, repo_root / 'config/apps/pattern_demo.yaml', key='composite',
                       roots=(repo_root / 'config',))
    assert [c.name for c in model.children] == ['program']
    assert [c.name for c in model.children[0].children] == ['track', 'hold']


@pytest.mark.parametrize('text, path, message', [
    ('composite: {name: app, entities: [{name: a}]}', 'composite.entities[0].kind', 'required field'),
    ('composite: {name: app, rate: -5}', 'composite.rate', 'greater than or equal to 0.01'),
    ('composite: {name: app, colour: red}', 'composite.colour', 'unknown field'),
    ('composite: {name: 1app}', 'composite.name', 'pattern'),
    ('composite: {name: app, entities: [{name: a, kind: K}, {name: a, kind: K}]}', 'composite', 'duplicate'),
    # a composite's own node (events read as lost from two nodes of one name)
    ('composite: {name: app, entities: [{name: scheduler, kind: K}]}', 'composite', "'scheduler' is the name of"),
    ('composite: {name: app, configure: [fast]}', 'composite', "unknown configuration 'fast'"),
    ('composite: {name: app, running: {initial: x, states: {y: {}}}}', 'composite.running', "initial state 'x'"),
    ('composite: {name: app, running: {initial: a, states: {a: {raise: [e_go]}}, transitions: [{from: a, to: a, '
     'when: e_go}]}}', 'composite.running', 'states a -> a would switch forever'),
    ('composite: {name: app, entities: [{include: missing.yaml}]}', 'composite.entities[0].include', 'cannot be read'),
])
def test_wrong_models_name_file_path_and_expectation(tmp_path, text, path, message):
    model_file = write(tmp_path, 'app.yaml', text)
    with pytest.raises(ModelError) as err:
        load_model(CompositeModel, model_file, key='composite')
    assert err.value.file == str(model_file)
    assert err.value.path == path
    assert message in err.value.message


def test_error_inside_an_included_file_names_that_file(tmp_path):
    write(tmp_path, 'task.yaml', 'name: T\nentities: [{name: x, kind: K, parameters: 3}]\n')
    model_file = write(tmp_path, 'app.yaml', 'composite: {name: app, entities: [{include: task.yaml}]}')
    with pytest.raises(ModelError) as err:
        load_model(CompositeModel, model_file, key='composite')
    assert err.value.file.endswith('task.yaml')
    assert err.value.path == 'entities[0].parameters'


def test_yaml_syntax_error_names_line(tmp_path):
    model_file = write(tmp_path, 'app.yaml', 'composite:\n  name: [app\n')
    with pytest.raises(ModelError) as err:
        load_model(CompositeModel, model_file, key='composite')
    assert 'YAML syntax error' in err.value.message and err.value.path.startswith('line')


def test_semantic_check_names_both_ports():
    out = PortSpec('pose', 'output', Float64MultiArray, type='pose', semantics='Pose(ee|base)@base')
    into = PortSpec('pose', 'input', Float64MultiArray, type='pose', semantics='Pose(ee|world)@world')
    with pytest.raises(SemanticMismatch, match=r'/a/x\.pose -> /a/y\.pose.*semantics'):
        check_connection(out, into, source_name='/a/x.pose', target_name='/a/y.pose')
    check_connection(out, PortSpec('pose', 'input', Float64MultiArray, type='pose', semantics='Pose( ee|base )@base'),
                     source_name='a', target_name='b')


def condition(name: str, **parameters):
    """A registered condition with its parameters (as a Monitor builds it)."""
    kind = CONDITIONS[name]
    return kind(kind.Parameters(**parameters))


def test_monitor_conditions():
    assert condition('above', threshold=1.0).holds([0.5, 1.5], age=0)
    assert not condition('below', threshold=0.0).holds([0.5], age=0)
    assert condition('outside', band=(-1, 1)).holds([2.0], age=0)
    assert condition('inside', band=(-1, 1)).holds([0.5, -1.0], age=0)  # the counterpart of outside
    assert not condition('inside', band=(-1, 1)).holds([0.5, 2.0], age=0)
    assert not condition('inside', band=(-1, 1)).holds([], age=0)
    assert not condition('inside', band=(0, 1)).holds(None, age=0)
    assert condition('nonfinite').holds([math.nan], age=0)
    assert condition('stale', timeout=0.1).holds(None, age=0.2)
    assert not condition('stale', timeout=0.1, grace=5.0).holds(None, age=0.2, seen=False)  # still coming up
    assert condition('stale', timeout=0.1, grace=5.0).holds(None, age=0.2, seen=True)  # went silent
    msg = Float64MultiArray(data=[1.0, 2.0])
    assert read_field(msg, 'data[1]') == [2.0] and read_field(msg, 'data') == [1.0, 2.0]
