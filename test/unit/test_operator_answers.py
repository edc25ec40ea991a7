"""What the operator services echo of a client's request (README "Operating a running
application"): a name a client sent comes back quoted, and a huge one shortened, so a refusal stays
one readable line whatever the client sent."""

from itasc_core.coordination.operator import quoted


def test_a_name_comes_back_quoted_as_sent():
    assert quoted('e_object_grasped') == "'e_object_grasped'"
    assert quoted('') == "''"
    assert quoted('e_a\nb') == "'e_a\\nb'"  # a control character is shown, not printed


def test_a_huge_name_comes_back_shortened_with_its_length():
    answer = quoted('e_' + 'x' * 5000)
    assert len(answer) < 120
    assert answer.startswith("'e_xxx") and answer.endswith('... (5002 characters)')
