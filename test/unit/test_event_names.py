"""The vocabulary of event names (itasc_core.communication.event_names): the paper's names, built in
one module only."""

import re
from pathlib import Path

from itasc_core.communication import event_names as names

ROOT = Path(__file__).resolve().parents[2]


def test_names_are_the_papers():
    assert names.event('ApproachObject', names.CONFIGURED) == 'e_ApproachObject_configured'
    assert names.event('AvoidObstacle', names.CONFIGURED) == 'e_AvoidObstacle_configured'
    assert names.named('high_accuracy_control') == 'e_high_accuracy_control'
    assert names.SAFETY_EVENT == 'e_emergency'
    assert names.to_child('ApproachObject', names.named('high_accuracy_control')) == \
        'e_ApproachObject_high_accuracy_control'
    assert names.from_parent('ApproachObject', 'e_ApproachObject_high_accuracy_control') == 'e_high_accuracy_control'
    assert names.owner_of('e_Task_1_faults_checked', names.FAULTS_CHECKED) == 'Task_1'
    assert names.owner_of('e_faults_checked', names.FAULTS_CHECKED) is None
    assert names.is_priority(names.event('child', names.EMERGENCY))


def test_no_event_name_is_built_outside_the_vocabulary():
    """Every composite builds its event names from the vocabulary: no hand-built ``f'e_...'``."""
    built = re.compile(r"""f['"]e_""")
    offenders = [f'{path.relative_to(ROOT)}:{n}' for folder in ('src', 'bringup', 'bench')
                 for path in (ROOT / folder).rglob('*.py') if path.name != 'event_names.py'
                 for n, line in enumerate(path.read_text().splitlines(), 1) if built.search(line)]
    assert offenders == []
