"""Whether the few numbers of a tick's vector are all finite: the check each step of the control
loop makes on what it reads and writes (paper §6: a fault leads to Safety, never to a NaN command).

For the handful of values a tick handles (joint positions, a command, a setpoint), one Python sum
over them is several times cheaper than numpy's reductions (``x.sum()`` goes through a Python
wrapper and the ufunc machinery; ``np.isfinite(x).all()`` twice); a NaN or an infinity makes the sum
non-finite, and only then (or when finite values overflow it) is the exact test made.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ['all_finite']


def all_finite(values: np.ndarray) -> bool:
    """Whether every value of the (small, 1-D) array ``values`` is finite."""
    return math.isfinite(sum(values.tolist())) or bool(np.isfinite(values).all())
