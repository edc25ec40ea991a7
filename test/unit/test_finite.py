"""The tick's finite check (itasc_core.finite)."""

import numpy as np
import pytest
from itasc_core.finite import all_finite


@pytest.mark.parametrize('values, finite', [
    ([0.0, 1.5, -2.0], True),
    ([], True),
    ([0.0, np.nan, 1.0], False),
    ([np.inf, 0.0], False),
    ([np.inf, -np.inf], False),  # their sum is NaN: not finite either way
    ([1e308, 1e308, -1e308], True),  # finite values whose sum overflows: the exact test decides
])
def test_all_finite_is_numpys_isfinite_all(values, finite):
    array = np.array(values, dtype=float)
    assert all_finite(array) is finite
    assert finite == bool(np.isfinite(array).all())
