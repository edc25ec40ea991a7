"""Where application models and robot descriptions live: ``config/`` in the share directory of
itasc_bringup (installed), else the repository's ``config/`` (running from source); the shipped
applications; and which folders a model's includes may reach."""

from __future__ import annotations

from pathlib import Path

__all__ = ['config_dirs', 'include_roots', 'known_apps']

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


def known_apps() -> list[str]:
    """The names of the shipped applications (``config/apps/<name>.yaml``)."""
    return sorted({p.stem for d in config_dirs() for p in (d / 'apps').glob('*.yaml')})


def include_roots(model: str | Path) -> tuple[Path, ...]:
    """The folders whose files the includes of model file ``model`` may reach: the folder tree of
    the model, the whole config folder when the model lies in one laid out as ours
    (``<config>/apps/<model>.yaml``), and the shipped config folders."""
    folder = Path(model).resolve().parent
    own = folder.parent if folder.name == 'apps' else folder
    return (own, *config_dirs())
