"""Reading the YAML files under config/ into model objects."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

from wallbot_sim import paths
from wallbot_sim.model import ParameterError, RobotParameters, Scenario
from wallbot_sim.model.scenario import SHAPES


def read_yaml(path: str | Path) -> Any:
    """Parsed YAML; a missing or malformed file is a ParameterError naming it."""
    try:
        with open(path, encoding='utf-8') as stream:
            return yaml.safe_load(stream)
    except OSError as error:
        raise ParameterError(f'cannot read {path}: {error.strerror}') from None
    except yaml.YAMLError as error:
        raise ParameterError(f'{path} is not valid YAML: {str(error).splitlines()[0]}') from None


def load_robot_parameters(path: str | Path | None = None) -> RobotParameters:
    """Robot parameters from ``path`` (default: the installed config/robot.yaml)."""
    path = path or paths.robot_yaml()
    try:
        return RobotParameters.from_mapping(read_yaml(path))
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
    try:
        return Scenario.from_mapping(read_yaml(path))
    except ParameterError as error:
        raise ParameterError(f'{path}: {error}') from None
