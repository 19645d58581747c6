"""The paper's scenarios (docs/model.md section 10): a reference, a duration and an initial state."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from wallbot_sim.model.errors import ParameterError
from wallbot_sim.model.keys import check_keys
from wallbot_sim.model.numbers import FINITE, POSITIVE
from wallbot_sim.model.robot import DOF, Robot
from wallbot_sim.model.trajectories import Circle, FigureEight, Reference, tangent_heading

SHAPES = ('circle', 'figure8')
SCENARIO_KEYS = ('name', 'reference', 'duration', 'initial_state')
INITIAL_STATE_KEYS = ('x', 'y', 'theta', 'at_rest')
REFERENCE_KEYS = {'circle': ('shape', 'radius', 'period', 'center'),
                  'figure8': ('shape', 'amplitude', 'period', 'center')}


@dataclass(frozen=True)
class InitialPose:
    """Where the robot starts; at rest, or moving with the reference at t = 0."""

    x: float
    y: float
    theta: float
    at_rest: bool


@dataclass(frozen=True)
class Scenario:
    """A named run of the paper."""

    name: str
    reference: Reference
    duration: float
    initial: InitialPose

    @classmethod
    def from_mapping(cls, values: Mapping[str, Any]) -> Scenario:
        """From a parsed scenario file (see config/circle.yaml)."""
        try:
            check_keys(values, SCENARIO_KEYS, 'scenario key')
            name = str(values['name'])
            reference = make_reference(values['reference'])
            duration = _number(values, 'duration')
            pose = values['initial_state']
            check_keys(pose, INITIAL_STATE_KEYS, 'initial_state key')
            at_rest = pose.get('at_rest', True)
            if not isinstance(at_rest, bool):
                raise ParameterError(f'initial_state at_rest must be true or false, got {at_rest!r}')
            initial = InitialPose(_number(pose, 'x'), _number(pose, 'y'), _number(pose, 'theta'), at_rest)
        except KeyError as missing:
            raise ParameterError(f'scenario is missing {missing.args[0]!r}') from None
        except (TypeError, AttributeError):
            raise ParameterError('scenario must be a mapping with name, reference, duration and initial_state') from None
        POSITIVE.check('scenario duration', duration)
        return cls(name, reference, duration, initial)

    def initial_state(self, robot: Robot) -> tuple[np.ndarray, np.ndarray]:
        """(q0, qd0): spins at 0, spin rates at their rolling values (so every constraint holds)."""
        pose = self.initial
        q0 = np.array([pose.x, pose.y, pose.theta, 0.0, 0.0, 0.0, 0.0])
        qd0 = np.zeros(DOF) if pose.at_rest else moving_start(robot, self.reference, pose.theta)
        return q0, qd0


def moving_start(robot: Robot, reference: Reference, theta: float, t: float = 0.0) -> np.ndarray:
    """qd at time t moving with the reference: its velocity, its turning rate, wheels rolling."""
    sample = reference.sample(t)
    heading = tangent_heading(sample)
    qd = np.zeros(DOF)
    qd[:2] = sample.velocity
    qd[2] = heading.rate if heading is not None else 0.0
    qd[3:] = robot.rolling_spin_rates(theta, sample.velocity, qd[2])
    return qd


def make_reference(values: Mapping[str, Any]) -> Reference:
    """A circle or figure-8 from its parameters (shape, radius or amplitude, period, center)."""
    shape = values.get('shape')
    if shape not in SHAPES:
        raise ParameterError(f'unknown reference shape {shape!r} (use {" or ".join(SHAPES)})')
    check_keys(values, REFERENCE_KEYS[shape], f'{shape} reference key')
    center = values.get('center', (0.0, 0.0))
    if not (isinstance(center, (list, tuple)) and len(center) == 2):
        raise ParameterError(f'reference center must be a pair [x, y], got {center!r}')
    center = (float(center[0]), float(center[1]))
    if shape == 'circle':
        return Circle(_number(values, 'radius'), _number(values, 'period'), center)
    return FigureEight(_number(values, 'amplitude'), _number(values, 'period'), center)


def _number(values: Mapping[str, Any], key: str) -> float:
    return FINITE.check(key, values[key])
