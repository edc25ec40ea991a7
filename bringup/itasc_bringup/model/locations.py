"""Where application models and robot descriptions live: ``config/`` in the share directory of
itasc_bringup (installed), else the repository's ``config/`` (running from source)."""

from __future__ import annotations

from pathlib import Path

__all__ = ['config_dirs']

_REPO_CONFIG = Path(__file__).resolve().parents[3] / 'config'


def config_dirs() -> list[Path]:
    """The config directories to look in, installed first."""
    dirs = []
    try:
        from ament_index_python.packages import get_package_share_directory
        dirs.append(Path(get_package_share_directory('itasc_bringup')) / 'config')
    except (ImportError, LookupError, ValueError):  # not installed, or no ament index
        pass
    if _REPO_CONFIG.is_dir():
        dirs.append(_REPO_CONFIG)
    return dirs
