"""Reading the YAML files under config/ into model objects."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

from wallbot_sim import paths
from wallbot_sim.model import ParameterError, RobotParameters, Scenario
from wallbot_sim.model.scenario import SHAPES
from wallbot_sim.model.world import World


def read_yaml(path: str | Path) -> Any:
    """Parsed YAML; a missing or malformed file is a ParameterError naming it."""
    try:
        with open(path, encoding='utf-8') as stream:
            return yaml.safe_load(stream)
    except OSError as error:
        raise ParameterError(f'cannot read {path}: {error.strerror}') from None
    except yaml.YAMLError as error:
        raise ParameterError(yaml_error(path, error)) from None


def yaml_error(path: str | Path, error: yaml.YAMLError) -> str:
    """'FILE:LINE:COLUMN: what is wrong' for a YAML syntax error (the line of the problem, 1-based)."""
    mark = getattr(error, 'problem_mark', None)
    where = f'{path}:{mark.line + 1}:{mark.column + 1}' if mark is not None else str(path)
    problem = getattr(error, 'problem', None) or str(error).splitlines()[0]
    return f'{where}: not valid YAML: {problem}'


def load_robot_parameters(path: str | Path | None = None) -> RobotParameters:
    """Robot parameters from ``path`` (default: the installed config/robot.yaml)."""
    path = path or paths.robot_yaml()
    values = read_yaml(path)  # its errors name the file (and the line) already
    try:
        return RobotParameters.from_mapping(values)
    except ParameterError as error:
        raise ParameterError(f'{path}: {error}') from None


def load_scenario(name_or_path: str | Path) -> Scenario:
    """A scenario by name (circle, figure8: the files under config/) or by YAML path."""
    text = str(name_or_path)
    if text in SHAPES:
        path = paths.scenario_yaml(text)
    elif text.endswith(('.yaml', '.yml')) or Path(text).is_file():
        path = Path(text)
    else:
        raise ParameterError(f'unknown scenario {text!r}: use {" or ".join(SHAPES)}, or a scenario YAML path')
    values = read_yaml(path)
    try:
        return Scenario.from_mapping(values)
    except ParameterError as error:
        raise ParameterError(f'{path}: {error}') from None


def load_world(path: str | Path | None) -> World | None:
    """The world file at ``path`` (docs/model.md 13.1), or None for none (a vertical, uniform wall)."""
    if not path:
        return None
    values = read_yaml(path)
    try:
        return World.from_mapping(values)
    except ParameterError as error:
        raise ParameterError(f'{path}: {error}') from None
