"""DDS settings the pattern relies on (paper §7.2: no event may be lost).

Call :func:`configure_dds` before ``rclpy.init``; it points Fast DDS at our profile
(``fastdds.xml``, intra-process delivery off) unless the user chose a profile of their own.
"""

from __future__ import annotations

import os
from pathlib import Path

__all__ = ['configure_dds', 'PROFILE']

PROFILE = Path(__file__).with_name('fastdds.xml')


def configure_dds() -> None:
    os.environ.setdefault('FASTRTPS_DEFAULT_PROFILES_FILE', str(PROFILE))
