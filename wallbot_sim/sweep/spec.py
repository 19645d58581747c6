"""A sweep spec: the run every robot makes and the robots, read from YAML.

    scenario: figure8            # circle, figure8 or a scenario YAML path
    constraints: belt,non_lateral,nonslip   # as simulate --constraints (default none)
    contact: ideal               # or coulomb (with controller: true)
    duration: 10.0               # s (default: the scenario's)
    controller: false            # the example tracking controller closes the loop
    controller_mass_scale: 1.0
    robot: config/robot.yaml     # the robot file the varied keys override (default: the installed one)
    world: config/world.yaml     # optional: the world file every robot runs on (robot by robot, python engine)
    grid:                        # full factorial over lists
      body_mass: [6.0, 8.0, 10.0]
    vary:                        # [low, high], drawn uniformly for `samples` robots with `seed`
      com_height: [0.03, 0.08]
    samples: 20
    seed: 1

Any key of the robot file may vary (``adhesion_force`` included). With ``grid`` and ``vary`` both,
every grid point is crossed with ``samples`` draws (one draw per robot). The robots are numbered in
a fixed order (grid points in the order of their lists, the last key fastest), so a sweep's robot i
is the same robot however the work is cut.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from wallbot_sim.config import load_robot_parameters, load_scenario, load_world, read_yaml
from wallbot_sim.model.keys import unknown_key
from wallbot_sim.control.tracking import DRIVEN
from wallbot_sim.model import DEFAULT_STEP, TIME_STEP, ConstraintSelection, ParameterError, RobotParameters, Scenario
from wallbot_sim.model.contact import CONTACT_MODELS
from wallbot_sim.model.parameters import OPTIONAL_BLOCKS, PYTHON_ONLY_BLOCKS
from wallbot_sim.model.scenario import SHAPES
from wallbot_sim.model.numbers import POSITIVE, NumberRange
from wallbot_sim.sweep.compute import RunSettings
from wallbot_sim.sweep.errors import SweepError

SETTINGS = ('scenario', 'constraints', 'tangent_heading', 'contact', 'duration', 'dt', 'controller',
            'controller_mass_scale', 'robot', 'world', 'chunk_size')
VARIATION = ('grid', 'vary', 'samples', 'seed')
CHUNK_ROBOT_STEPS = 1_200_000
"""Robot-steps of a chunk by default: the work of one task, what a Ctrl-C loses at most per worker (its memory
is ``compute.BLOCK`` or ``compute.BATCH_BLOCK`` instants of its robots at most, whatever their duration)."""
MAX_CHUNK_SIZE = 250
ROBOT_KEYS = tuple(f.name for f in fields(RobotParameters) if f.name not in OPTIONAL_BLOCKS)


@dataclass(frozen=True)
class SweepSpec:
    settings: RunSettings
    base: RobotParameters
    """The robot file's parameters, which every robot's varied keys override."""
    varied: tuple[str, ...]
    """The varied robot-file keys, grid keys first."""
    robots: tuple[dict[str, Any], ...]
    """Per robot, its value of each varied key."""
    chunk_size: int

    def parameters(self, index: int) -> RobotParameters:
        """Robot ``index``'s parameters (the robot file with its varied keys)."""
        return self.base.replace(**self.robots[index])

    def chunks(self) -> list[range]:
        """The robot indices of each chunk, in order."""
        size = len(self.robots)
        return [range(start, min(start + self.chunk_size, size)) for start in range(0, size, self.chunk_size)]


def load_spec(path: str | Path) -> SweepSpec:
    """The spec at ``path``; SweepError (or ParameterError) naming the key that is wrong."""
    values = read_yaml(path)
    try:
        return parse_spec(values, Path(path).parent)
    except (SweepError, ParameterError) as error:
        raise SweepError(f'{path}: {error}') from None


def parse_spec(values: Any, folder: Path = Path('.')) -> SweepSpec:
    """A spec from its parsed YAML mapping; relative file paths in it are relative to ``folder``."""
    reason = unknown_key(values, SETTINGS + VARIATION, 'sweep spec key')
    if reason is not None:
        raise SweepError(reason)
    settings = _settings(values, folder)
    robot = values.get('robot')
    if robot is not None and not isinstance(robot, str):
        raise SweepError(f'robot must be a robot file path, got {robot!r}')
    base = load_robot_parameters(None if robot is None else folder / robot)
    blocks = [block for block in PYTHON_ONLY_BLOCKS if getattr(base, block) is not None]
    if blocks:
        raise SweepError(f'the robot file\'s {blocks[0]} block runs on the python engine only and a sweep runs on the '
                         'batch (numba): drop the block, or simulate --engine python robot by robot')
    grid = _grid(values.get('grid'))
    vary = _vary(values.get('vary'))
    both = set(grid) & set(vary)
    if both:
        raise SweepError(f'{sorted(both)[0]!r} is in both grid and vary: give it in one')
    if not grid and not vary:
        raise SweepError('nothing varies: give grid (lists) and/or vary ([low, high] ranges) of robot-file keys')
    samples = _count(values, 'samples', 1 if not vary else None)
    if not vary and 'samples' in values:
        raise SweepError('samples draws the vary ranges: give vary, or drop samples')
    points = [dict(zip(grid, combination)) for combination in itertools.product(*grid.values())]
    draws = np.random.default_rng(_seed(values)).uniform(
        [low for low, _high in vary.values()], [high for _low, high in vary.values()],
        size=(len(points) * samples, len(vary)))
    robots = tuple({**point, **{key: float(value) for key, value in zip(vary, draw)}}
                   for point, draw in zip((p for p in points for _ in range(samples)), draws))
    for robot in robots:
        try:
            base.replace(**robot)
        except ParameterError as error:
            raise SweepError(f'robot {robot}: {error}') from None
    chunk_size = _count(values, 'chunk_size', default_chunk_size(settings))
    return SweepSpec(settings, base, tuple(grid) + tuple(vary), robots, chunk_size)


def default_chunk_size(settings: RunSettings) -> int:
    """Robots per chunk when the spec does not say: CHUNK_ROBOT_STEPS of them, 1 .. MAX_CHUNK_SIZE."""
    return max(1, min(MAX_CHUNK_SIZE, CHUNK_ROBOT_STEPS // (settings.steps + 1)))


def _settings(values: Mapping[str, Any], folder: Path) -> RunSettings:
    name = values.get('scenario', 'circle')
    if not isinstance(name, str):
        raise SweepError(f'scenario must be circle, figure8 or a scenario YAML path, got {name!r}')
    scenario: Scenario = load_scenario(name if name in SHAPES else folder / name)
    contact = values.get('contact', 'ideal')
    if contact not in CONTACT_MODELS:
        raise SweepError(f'contact must be one of {", ".join(CONTACT_MODELS)}, got {contact!r}')
    controller = _flag(values, 'controller')
    scale = _number(values, 'controller_mass_scale', POSITIVE, 1.0)
    if controller:
        for key in ('constraints', 'tangent_heading'):
            if key in values:
                raise SweepError(f'{key}: with controller: true the driven robot runs '
                                 f'({", ".join(DRIVEN.active_names())}, no trajectory task); drop it')
        selection = DRIVEN
    else:
        if scale != 1.0:
            raise SweepError('controller_mass_scale needs controller: true')
        text = values.get('constraints', 'none')
        if not isinstance(text, str):
            raise SweepError(f'constraints must be a comma list (or none), got {text!r}')
        heading = values.get('tangent_heading')
        if heading is not None and not isinstance(heading, bool):
            raise SweepError(f'tangent_heading must be true or false, got {heading!r}')
        selection = ConstraintSelection.parse(text, trajectory=True, tangent_heading=heading)
    if contact == 'coulomb' and selection.trajectory:
        raise SweepError('contact: coulomb needs controller: true (the trajectory task\'s force is a virtual '
                         'actuator, not friction)')
    duration = _number(values, 'duration', POSITIVE, scenario.duration)
    time_step = _number(values, 'dt', TIME_STEP, DEFAULT_STEP)
    world = values.get('world')
    if world is not None and not isinstance(world, str):
        raise SweepError(f'world must be a world file path, got {world!r}')
    return RunSettings(scenario, selection, contact, duration, time_step, controller, scale,
                       None if world is None else load_world(folder / world))


def _grid(grid: Any) -> dict[str, list]:
    if grid is None:
        return {}
    if not isinstance(grid, Mapping):
        raise SweepError(f'grid must map robot-file keys to lists of values, got {grid!r}')
    for key, values in grid.items():
        _robot_key('grid', key)
        if not isinstance(values, list) or not values:
            raise SweepError(f'grid: {key} must be a non-empty list of values, got {values!r}')
    return dict(grid)


def _vary(vary: Any) -> dict[str, tuple[float, float]]:
    if vary is None:
        return {}
    if not isinstance(vary, Mapping):
        raise SweepError(f'vary must map robot-file keys to [low, high] ranges, got {vary!r}')
    ranges = {}
    for key, span in vary.items():
        _robot_key('vary', key)
        if (not isinstance(span, list) or len(span) != 2
                or not all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in span)
                or span[0] > span[1]):
            raise SweepError(f'vary: {key} must be a range [low, high] of two finite numbers, low <= high, '
                             f'got {span!r}')
        ranges[key] = (float(span[0]), float(span[1]))
    return ranges


def _robot_key(section: str, key: Any) -> None:
    reason = unknown_key({key: None}, ROBOT_KEYS, f'{section}: robot-file key')
    if reason is not None:
        raise SweepError(reason)
    if key == 'com_offset' and section == 'vary':
        raise SweepError('vary: com_offset is a pair; give its values in grid')


def _flag(values: Mapping[str, Any], key: str) -> bool:
    value = values.get(key, False)
    if not isinstance(value, bool):
        raise SweepError(f'{key} must be true or false, got {value!r}')
    return value


def _number(values: Mapping[str, Any], key: str, allowed: NumberRange, default: float) -> float:
    return allowed.check(key, values[key]) if key in values else default


def _count(values: Mapping[str, Any], key: str, default: int | None) -> int:
    if key not in values:
        if default is None:
            raise SweepError(f'{key} is missing: how many robots to draw from the vary ranges')
        return default
    value = values[key]
    if isinstance(value, bool) or not isinstance(value, int) or value < 1:
        raise SweepError(f'{key} must be a whole number >= 1, got {value!r}')
    return value


def _seed(values: Mapping[str, Any]) -> int:
    value = values.get('seed', 0)
    if isinstance(value, bool) or not isinstance(value, int) or value < 0:
        raise SweepError(f'seed must be a whole number >= 0, got {value!r}')
    return value
