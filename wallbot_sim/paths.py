"""Locate wallbot_sim's installed data files (config/*.yaml).

Lookup order of :func:`config_dir` (first directory holding ``robot.yaml`` wins):

1. ``$WALLBOT_SIM_CONFIG_DIR`` if set (explicit override, used as-is).
2. ``<repo>/config`` when running from a source checkout (``pip install -e .``,
   ``colcon build --symlink-install`` or plain ``PYTHONPATH``): detected by a
   ``package.xml`` next to the ``wallbot_sim`` package directory. Preferred over
   the ament share so edits to the checkout are never shadowed by stale copies.
3. ``<ament share>/wallbot_sim/config`` if ``ament_index_python`` is importable
   and the package is in the ament index (``colcon build`` + ``source install/setup.bash``).
4. ``wallbot_sim/_data/config`` package data (``pip install .``).
"""
from __future__ import annotations

import os
from pathlib import Path

PACKAGE_NAME = 'wallbot_sim'
ENV_OVERRIDE = 'WALLBOT_SIM_CONFIG_DIR'
_MARKER = 'robot.yaml'
_PKG_DIR = Path(__file__).resolve().parent


def _source_tree_config() -> Path | None:
    """``<repo>/config`` if this module runs from a source checkout, else None."""
    root = _PKG_DIR.parent
    if (root / 'package.xml').is_file() and (root / 'config' / _MARKER).is_file():
        return root / 'config'
    return None


def _ament_share_config() -> Path | None:
    """``share/wallbot_sim/config`` from the ament index, else None."""
    try:
        from ament_index_python.packages import get_package_share_directory
    except ImportError:
        return None
    try:
        share = Path(get_package_share_directory(PACKAGE_NAME))
    except Exception:  # PackageNotFoundError, or AMENT_PREFIX_PATH unset (OSError)
        return None
    cfg = share / 'config'
    return cfg if (cfg / _MARKER).is_file() else None


def _package_data_config() -> Path | None:
    """``wallbot_sim/_data/config`` shipped as package data by ``pip install .``."""
    cfg = _PKG_DIR / '_data' / 'config'
    return cfg if (cfg / _MARKER).is_file() else None


def config_candidates() -> list[Path]:
    """All existing config directories, in lookup order (for diagnostics)."""
    found = []
    override = os.environ.get(ENV_OVERRIDE)
    if override:
        found.append(Path(override))
    for finder in (_source_tree_config, _ament_share_config, _package_data_config):
        cfg = finder()
        if cfg is not None and cfg not in found:
            found.append(cfg)
    return found


def config_dir() -> Path:
    """Return the directory holding robot.yaml and the scenario YAML files.

    Raises FileNotFoundError if no candidate location exists.
    """
    found = config_candidates()
    if not found:
        raise FileNotFoundError(
            f'wallbot_sim config directory not found (no {_MARKER} in the source tree, '
            f'the ament index or the installed package); set ${ENV_OVERRIDE} to override')
    return found[0]


def robot_yaml() -> Path:
    """Path of the robot description ``robot.yaml``."""
    return config_dir() / 'robot.yaml'


def scenario_yaml(name: str) -> Path:
    """Path of scenario ``<name>.yaml`` (e.g. ``circle``, ``figure8``).

    Raises FileNotFoundError for an unknown scenario, listing the known ones.
    """
    cfg = config_dir()
    path = cfg / f'{name}.yaml'
    if not path.is_file():
        known = sorted(p.stem for p in cfg.glob('*.yaml') if p.stem != 'robot')
        raise FileNotFoundError(f'unknown scenario {name!r} in {cfg}; known: {known}')
    return path
