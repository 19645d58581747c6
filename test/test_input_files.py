"""Every input file refuses what it does not know, naming the key and the closest valid one, and a
YAML syntax error names the file, line and column (robot, scenario and sweep files alike)."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from cli_helpers import assert_one_line_error, simulate
from wallbot_sim import paths
from wallbot_sim.config import load_robot_parameters, load_scenario, load_world
from wallbot_sim.model import ParameterError
from wallbot_sim.model.keys import unknown_key
from wallbot_sim.sweep.errors import SweepError
from wallbot_sim.sweep.spec import load_spec

CIRCLE = yaml.safe_load(paths.scenario_yaml('circle').read_text())


def scenario_file(tmp_path: Path, change) -> Path:
    values = yaml.safe_load(yaml.safe_dump(CIRCLE))
    change(values)
    path = tmp_path / 'scenario.yaml'
    path.write_text(yaml.safe_dump(values))
    return path


@pytest.mark.parametrize('change, words', [
    (lambda v: v['reference'].update(centre=[0.5, 0.5]),
     "unknown circle reference key 'centre' (did you mean 'center'?)"),
    (lambda v: v['initial_state'].update(at_rset=False),
     "unknown initial_state key 'at_rset' (did you mean 'at_rest'?)"),
    (lambda v: v.update(durration=3.0), "unknown scenario key 'durration' (did you mean 'duration'?)"),
    (lambda v: v.update(colour='red'), "unknown scenario key 'colour' (known: duration, initial_state, name, "
                                       "reference)"),
    (lambda v: v['reference'].update(amplitude=1.0), "unknown circle reference key 'amplitude'"),
    (lambda v: v['initial_state'].update(at_rest='no'), "initial_state at_rest must be true or false, got 'no'"),
    (lambda v: v.update(initial_state=[0.8, 0.0]), 'expected a mapping of initial_state keys to values'),
])
def test_a_scenario_file_refuses_what_it_does_not_know(tmp_path, change, words):
    path = scenario_file(tmp_path, change)
    with pytest.raises(ParameterError) as error:
        load_scenario(path)
    assert str(error.value).startswith(f'{path}: {words}')


def test_a_robot_file_names_the_closest_key(tmp_path):
    values = yaml.safe_load(paths.robot_yaml().read_text())
    values['wall_fricton'] = values.pop('wall_friction')
    path = tmp_path / 'robot.yaml'
    path.write_text(yaml.safe_dump(values))
    with pytest.raises(ParameterError, match=r"unknown robot parameter 'wall_fricton' \(did you mean "
                                             r"'wall_friction'\?\)"):
        load_robot_parameters(path)


@pytest.mark.parametrize('text, words', [
    ('scenario: circle\nsampels: 3\n', "unknown sweep spec key 'sampels' (did you mean 'samples'?)"),
    ('scenario: circle\ngrid:\n  body_mas: [8.0, 9.0]\n', "unknown grid: robot-file key 'body_mas' (did you mean "
                                                          "'body_mass'?)"),
])
def test_a_sweep_spec_names_the_closest_key(tmp_path, text, words):
    path = tmp_path / 'sweep.yaml'
    path.write_text(text)
    with pytest.raises(SweepError, match=words.replace('(', r'\(').replace(')', r'\)').replace('?', r'\?')):
        load_spec(path)


@pytest.mark.parametrize('text, words', [
    ('inclnation: 45\n', "unknown world key 'inclnation' (did you mean 'inclination'?)"),
    ('inclination: 200\n', 'inclination must be in [0, 180], got 200'),
    ('patches:\n  - {x: [0, 1], y: [0, 1], wall_fricton: 0.3, kinetic_friction: 0.2}\n',
     "unknown patches[0] key 'wall_fricton' (did you mean 'wall_friction'?)"),
    ('patches:\n  - {x: [0, 1], y: [0, 1], wall_friction: 0.3, kinetic_friction: 0.4}\n',
     'patches[0] kinetic_friction must be <= its wall_friction (0.3), got 0.4'),
    ('patches:\n  - {x: [1, 0], y: [0, 1], wall_friction: 0.3, kinetic_friction: 0.2}\n',
     'patches[0] x must be [low, high] with low < high, got [1, 0]'),
    ('seams:\n  - {from: [0, 1], to: [2, 1]}\n', "seams[0] needs 'width'"),
    ('seams:\n  - {from: [0, 1], to: [0, 1], width: 0.004}\n', 'seams[0] from and to must differ'),
    ('seams: {from: [0, 1]}\n', 'seams must be a list'),
])
def test_a_world_file_refuses_what_it_does_not_know(tmp_path, text, words):
    path = tmp_path / 'world.yaml'
    path.write_text(text)
    with pytest.raises(ParameterError) as error:
        load_world(path)
    assert str(error.value).startswith(f'{path}: {words}'), str(error.value)
    assert '\n' not in str(error.value)


def test_the_example_world_has_a_patch_and_a_seam():
    world = load_world(paths.config_dir() / 'world.yaml')
    assert world.inclination == 90.0 and len(world.patches) == 1 and len(world.seams) == 1


@pytest.mark.parametrize('loader', [load_robot_parameters, load_scenario, load_spec, load_world])
def test_a_yaml_syntax_error_names_the_file_and_line_once(tmp_path, loader):
    path = tmp_path / 'broken.yaml'
    path.write_text('name: circle\nreference:\n  shape: circle\n  radius: [1.0\nduration: 20.0\n')
    with pytest.raises((ParameterError, SweepError)) as error:
        loader(path)
    message = str(error.value)
    assert message.startswith(f'{path}:5:') and 'not valid YAML' in message, message
    assert message.count(str(path)) == 1 and '\n' not in message


def test_the_closest_key_is_named_only_when_one_is_close():
    assert unknown_key({'x': 1}, ('x', 'y'), 'pose key') is None
    assert unknown_key({'z': 1}, ('x', 'y'), 'pose key') == "unknown pose key 'z' (known: x, y)"


def test_simulate_refuses_a_misspelt_scenario_in_one_line(tmp_path):
    path = scenario_file(tmp_path, lambda v: v['reference'].update(centre=[0.5, 0.5]))
    assert_one_line_error(simulate('--scenario', path, '--constraints', 'belt', '--duration', '0.01', '--csv',
                                   tmp_path / 'out.csv'), "unknown circle reference key 'centre'")
