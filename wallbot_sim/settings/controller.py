"""The tracking controller node's settings (``nodes.controller``)."""

from __future__ import annotations

from dataclasses import dataclass

from wallbot_sim.control.sampling import CONTROL_RATE_HZ, MAX_WHEEL_TORQUE
from wallbot_sim.control.tracking import GAIN_RANGES, ControllerGains
from wallbot_sim.model.numbers import NumberRange
from wallbot_sim.model.simulation import ENGINES, NUMBA
from wallbot_sim.settings.common import WHEEL_TORQUE_LIMIT, recorder_wait, sim_time
from wallbot_sim.settings.table import setting, table_of

GAINS = ControllerGains()


@dataclass(frozen=True)
class ControllerSettings:
    """The tracking controller's parameters."""

    rate_hz: int = setting(CONTROL_RATE_HZ, 'control rate in simulation time (Hz; 1000 / rate_hz should be a whole '
                                            'number of dynamics steps)', NumberRange(1, 1000))
    alpha: float = setting(GAINS.alpha, 'velocity gain 2 alpha of the look-ahead task (1/s)', GAIN_RANGES['alpha'])
    beta: float = setting(GAINS.beta, 'position gain beta^2 of the look-ahead task (1/s)', GAIN_RANGES['beta'])
    look_ahead: float = setting(GAINS.look_ahead, 'distance of the steered point ahead of the centre (m)',
                                GAIN_RANGES['look_ahead'])
    integral: float = setting(GAINS.integral, 'integral gain (1/s^3; 0 = off)', GAIN_RANGES['integral'])
    integral_zone: float = setting(GAINS.integral_zone, 'integrate the error only within this distance of the path '
                                                        '(m)', GAIN_RANGES['integral_zone'])
    robot_file: str = setting('', "the controller's robot parameter YAML; empty = installed config/robot.yaml",
                              read_only=True)
    mass_scale: float = setting(1.0, "body_mass of the controller's robot copy relative to the file's (model "
                                     'mismatch)', NumberRange(1e-3, 1e3))
    max_wheel_torque: float = setting(MAX_WHEEL_TORQUE, "commands are clamped to +-this (N m; the dynamics' limit)",
                                      WHEEL_TORQUE_LIMIT)
    engine: str = setting(NUMBA, "how the control law computes its inverse dynamics: numba (the batch's compiled "
                                 'kernel, the same torques as the model to round-off at a fraction of the CPU; it '
                                 "compiles on a machine's first use, then loads from the cache), or python (the model "
                                 'as written)', choices=ENGINES, read_only=True)
    wait_for_recorder: bool = recorder_wait('subscribe odom (and so let the dynamics start)')
    use_sim_time: bool = sim_time()


CONTROLLER = table_of(ControllerSettings)
GAIN_NAMES = ('alpha', 'beta', 'look_ahead', 'integral', 'integral_zone')
