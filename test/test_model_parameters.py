"""Robot parameters are validated on load: every bad value is an error naming its key."""

from __future__ import annotations

import math

import pytest
import yaml

from wallbot_sim.config import load_robot_parameters, load_scenario
from wallbot_sim.model import ParameterError, RobotParameters
from wallbot_sim.paths import robot_yaml


def defaults() -> dict:
    return yaml.safe_load(robot_yaml().read_text())


def test_config_file_holds_model_md_defaults():
    assert load_robot_parameters() == RobotParameters()


@pytest.mark.parametrize('key, value, words', [
    ('body_mass', -1.0, 'body_mass must be > 0'),
    ('wheel_radius', 0.0, 'wheel_radius must be > 0'),
    ('wheel_spin_inertia', math.nan, 'wheel_spin_inertia must be a finite number, got nan'),
    ('gravity', math.inf, 'gravity must be a finite number, got inf'),
    ('half_track', 'wide', 'half_track must be a finite number'),
    ('wall_friction', True, 'wall_friction must be a finite number'),
    ('rolling_resistance', -0.01, 'rolling_resistance must be >= 0'),
    ('com_offset', [0.1], 'com_offset must be a pair'),
    ('com_offset', ['a', 0.0], 'com_offset must be a finite number'),
    ('kinetic_friction', 0.8, r'kinetic_friction must be <= wall_friction \(0.7\), got 0.8'),
    ('kinetic_friction', 0.0, 'kinetic_friction must be > 0'),
    ('adhesion_force', -5.0, 'adhesion_force must be > 0'),
    ('adhesion_force', 'strong', 'adhesion_force must be a finite number'),
    ('stick_velocity', 0.0, 'stick_velocity must be > 0'),
])
def test_bad_values_are_refused_with_their_name(key, value, words):
    values = defaults()
    values[key] = value
    with pytest.raises(ParameterError, match=words):
        RobotParameters.from_mapping(values)


def test_unknown_and_missing_keys_are_refused():
    values = defaults()
    values['body_mas'] = 8.0
    with pytest.raises(ParameterError, match="unknown robot parameter 'body_mas'"):
        RobotParameters.from_mapping(values)
    values = defaults()
    del values['gravity']
    with pytest.raises(ParameterError, match="missing robot parameter 'gravity'"):
        RobotParameters.from_mapping(values)


def test_a_bad_file_names_the_file_and_the_key(tmp_path):
    values = defaults()
    values['wheel_mass'] = -0.25
    path = tmp_path / 'robot.yaml'
    path.write_text(yaml.safe_dump(values))
    with pytest.raises(ParameterError, match=r'robot\.yaml: wheel_mass must be > 0'):
        load_robot_parameters(path)
    path.write_text('body_mass: [unclosed')
    with pytest.raises(ParameterError, match='not valid YAML'):
        load_robot_parameters(path)
    with pytest.raises(ParameterError, match='cannot read'):
        load_robot_parameters(tmp_path / 'missing.yaml')


def test_scenarios_load_and_bad_ones_are_refused(tmp_path):
    assert load_scenario('circle').duration == 20.0
    assert load_scenario('figure8').duration == 30.0
    with pytest.raises(ParameterError, match="unknown scenario 'square'"):
        load_scenario('square')
    path = tmp_path / 'bad.yaml'
    path.write_text(yaml.safe_dump({'name': 'x', 'reference': {'shape': 'circle', 'radius': -1, 'period': 5},
                                    'duration': 3, 'initial_state': {'x': 0, 'y': 0, 'theta': 0}}))
    with pytest.raises(ParameterError, match='radius must be > 0, got -1'):
        load_scenario(path)


def test_adhesion_force_overrides_the_safety_factor():
    from wallbot_sim.model import adsorption_analysis
    default = adsorption_analysis(RobotParameters())
    assert default.applied_force == pytest.approx(1.5 * default.minimum_force)
    assert adsorption_analysis(RobotParameters(adhesion_force=100)).applied_force == 100.0
