"""The model reference is generated from the schema (bringup/itasc_bringup/model/reference.py):
docs/model.md and docs/model.schema.json must be what `itasc-model docs` / `schema` write today,
the schema must accept every shipped model and refuse a wrong one, and `itasc-model check`
validates without starting anything."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import jsonschema
import pytest
import yaml

from itasc_bringup.model.locations import config_dirs
from itasc_bringup.model.reference import json_schema, markdown

ROOT = Path(__file__).resolve().parents[2]
REGENERATE = 'regenerate with: itasc-model docs && itasc-model schema --out docs/model.schema.json'


def test_docs_model_md_is_up_to_date():
    assert (ROOT / 'docs' / 'model.md').read_text() == markdown(examples=config_dirs()[-1]), REGENERATE


def test_docs_model_schema_is_up_to_date():
    assert json.loads((ROOT / 'docs' / 'model.schema.json').read_text()) == json_schema(), REGENERATE


@pytest.mark.parametrize('app', sorted((ROOT / 'config' / 'apps').glob('*.yaml')), ids=lambda p: p.stem)
def test_the_schema_accepts_every_shipped_application(app):
    data = yaml.safe_load(app.read_text())
    if 'application' not in data:
        pytest.skip('a composition model (composite:), not an application model')
    jsonschema.validate(data, json_schema())


def test_the_schema_refuses_what_the_loader_refuses():
    data = yaml.safe_load((ROOT / 'config' / 'apps' / 'approach_object.yaml').read_text())
    data['application']['rate'] = -1
    with pytest.raises(jsonschema.ValidationError, match='-1'):
        jsonschema.validate(data, json_schema())


def test_the_reference_documents_every_field_and_every_kind():
    text = markdown(examples=config_dirs()[-1])
    for section in ('Application', 'Program', 'CartesianTask', 'PointPlaneTask', 'PController', 'PIDController',
                    'MinimumJerkSetpoint', 'HoldSetpoint', 'AboveMonitor', 'InsideMonitor', 'SimulatedDriver',
                    'Ros2ControlDriver', 'WdlsSolver', 'QpSolver'):
        assert f'\n## {section}\n' in text
    rows = [line for line in text.splitlines() if line.startswith('| `') and line.count('|') >= 5]
    undocumented = [row for row in rows if row.rstrip().endswith('|  |')]
    assert not undocumented, undocumented
    for kind in ('type: cartesian', 'type: distance', 'type: point_plane', 'kind: qp', 'kind: wdls', 'condition: above',
                 'condition: inside', 'kind: simulated', 'kind: ros2_control', 'kind: pid', 'kind: p',
                 'kind: minimum_jerk', 'kind: hold', 'kind: topic'):
        assert f'**{kind}**' in text
    assert 'NearMonitor' not in text and 'HorizontalDistanceTask' not in text  # the test package's kinds
    assert 'No shipped model uses it yet' not in text  # every kind has an example: a shipped one, or its own


def test_the_examples_kinds_give_are_sections_the_model_takes():
    from pydantic import TypeAdapter

    from itasc_bringup.model import schema
    sections = {'itasc.task_types': schema.Task, 'itasc.conditions': schema.Monitor,
                'itasc.controllers': schema.Controller, 'itasc.setpoint_generators': schema.Setpoint,
                'itasc.drivers': schema.Driver, 'itasc.solvers': schema.Solver}
    checked = []
    for registry, field, _ in schema.KIND_SECTIONS:
        for name, kind in registry.kinds().items():
            example = getattr(kind, 'example', None)
            if example is None:
                continue
            value = TypeAdapter(sections[registry.group]).validate_python(yaml.safe_load(example))
            assert getattr(value, field) == name
            checked.append(name)
    assert {'fixed', 'hold', 'periodic', 'topic', 'trapezoidal', 'point_plane', 'inside', 'stale', 'nonfinite'} <= \
        set(checked)


def test_check_validates_without_starting_anything(tmp_path):
    bad = tmp_path / 'bad.yaml'
    bad.write_text('application: {name: x, rate: .nan}\n')
    cli = [sys.executable, '-m', 'itasc_bringup.model.cli', 'check']
    good = subprocess.run([*cli, 'approach_object'], capture_output=True, text=True, timeout=60)
    assert good.returncode == 0 and 'ok (' in good.stdout, good.stderr
    wrong = subprocess.run([*cli, str(bad)], capture_output=True, text=True, timeout=60)
    assert wrong.returncode == 2 and str(bad) in wrong.stderr and 'rate' in wrong.stderr, wrong.stderr
    assert 'Traceback' not in wrong.stderr
