"""A tracking controller for the driven robot: model-based feed-forward plus feedback.

Feed-forward is the model's inverse dynamics. The controller's own copy of the robot (its
parameters may differ from the simulator's) is given the structural constraints (belt,
non-lateral, nonslip) and a look-ahead point task; the Udwadia-Phohomsiri solution at the
measured state yields the constraint wrench that task needs, which docs/model.md section 8 maps to
side drive forces F_L, F_R and motor torques tau = r F + the torque on the side's wheels.
The task's Baumgarte terms are a PD feedback on the point's error; an integral term on the
centre's error (integrated only within ``integral_zone`` of the path) removes the steady error
that wrong parameters leave, such as a wrong mass under gravity.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from wallbot_sim.model import BaumgarteGains, ConstraintSelection, DriveForces, ParameterError, Reference, Robot
from wallbot_sim.model.constraint_set import build_modules
from wallbot_sim.model.constraints import LookAheadPointTask
from wallbot_sim.model.constraints.look_ahead import point_reference
from wallbot_sim.model.numbers import NumberRange
from wallbot_sim.model.outputs import drive_forces, side_motor_torques
from wallbot_sim.model.constrained_problem import constrained_motion
from wallbot_sim.model.simulation import ENGINES, NUMBA, PYTHON
from wallbot_sim.model.trajectories import ReferenceSample

DRIVEN = ConstraintSelection.structural(trajectory=False)
"""The constraints of the driven robot: belts, no side slip, wheels rolling on the wall."""


GAIN_RANGES = {'alpha': NumberRange(1e-3, 1e4), 'beta': NumberRange(1e-3, 1e4), 'look_ahead': NumberRange(1e-4, 10.0),
               'integral': NumberRange(0.0, 1e6), 'integral_zone': NumberRange(1e-4, 10.0)}
"""The accepted values of each of the ControllerGains (the controller node's parameters of the same names)."""


@dataclass(frozen=True)
class ControllerGains:
    """Feedback of the tracking controller."""

    alpha: float = 10.0
    """Velocity gain of the look-ahead task, 2 alpha (1/s)."""
    beta: float = 10.0
    """Position gain of the look-ahead task, beta^2 (1/s^2)."""
    look_ahead: float = 0.05
    """Distance of the steered point ahead of the centre (m)."""
    integral: float = 50.0
    """Integral gain (1/s^3): force -integral m_t (integral of the centre's error)."""
    integral_zone: float = 0.05
    """The error is integrated only while the centre is this close to its reference (m)."""

    def __post_init__(self) -> None:
        for name, allowed in GAIN_RANGES.items():
            allowed.check(name, getattr(self, name))


@dataclass(frozen=True)
class MotorCommand:
    """One controller output."""

    tau_left: float
    tau_right: float
    drive: DriveForces
    """Side drive forces the command stands for (N)."""
    tracking_error: float
    """Distance of the centre from its reference (m)."""


class TrackingController:
    """Motor torques that make a driven robot follow a reference with its centre.

    ``engine`` computes the inverse dynamics: ``python`` by the model's modules and solve, ``numba`` by
    the compiled kernel (the same constraint force to round-off, a fraction of the CPU a call).
    """

    def __init__(self, robot: Robot, reference: Reference | None = None,
                 gains: ControllerGains | None = None, engine: str = PYTHON) -> None:
        if engine not in ENGINES:
            raise ParameterError(f'unknown engine {engine!r} (use {" or ".join(ENGINES)})')
        self.robot = robot
        self.gains = gains or ControllerGains()
        self.reference = reference
        self.engine = engine
        self._error_integral = np.zeros(2)
        self._compiled = None
        self._baumgarte: tuple[ControllerGains, BaumgarteGains] | None = None
        if engine == NUMBA:
            # imported only here: numba takes about 0.4 s to import, which the python engine need not pay
            from wallbot_sim.model.compiled import CompiledInverseDynamics
            self._compiled = CompiledInverseDynamics()

    def reset(self) -> None:
        """Forget the integrated error."""
        self._error_integral = np.zeros(2)

    def update(self, t: float, q: np.ndarray, qd: np.ndarray, dt: float) -> MotorCommand:
        """The torques to hold for the next ``dt`` seconds, from the state measured at t."""
        if self.reference is None:
            raise ParameterError('the controller has no reference yet')
        gains = self.gains
        sample = self.reference.sample(t)
        constraint_force = self._constraint_force(t, sample, q, qd)
        error = q[:2] - np.asarray(sample.position)
        distance = math.hypot(error[0], error[1])
        if distance < gains.integral_zone:
            self._error_integral += error * dt
        wrench = constraint_force[:3].copy()
        wrench[:2] -= gains.integral * self.robot.total_mass * self._error_integral
        params = self.robot.params
        drive = drive_forces(q[2], wrench, params.half_track)
        tau_left, tau_right = side_motor_torques(drive, constraint_force[3:], params.wheel_radius)
        return MotorCommand(tau_left, tau_right, drive, distance)

    def _constraint_force(self, t: float, sample: ReferenceSample, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        """Q_c of the robot copy under the driven set and the look-ahead point task at (t, q, qd)."""
        gains = self.gains
        baumgarte = self._baumgarte_gains()
        if self._compiled is not None:
            return self._compiled.constraint_force(self.robot, baumgarte, DRIVEN,
                                                   point_reference(sample, gains.look_ahead), gains.look_ahead, q, qd)
        task = LookAheadPointTask(self.reference, baumgarte, gains.look_ahead)
        modules = build_modules(DRIVEN, self.robot, None, baumgarte) + [task]
        return constrained_motion(self.robot, modules, t, q, qd).constraint_force

    def _baumgarte_gains(self) -> BaumgarteGains:
        """The task's and the structural modules' gains (the same object while the gains are)."""
        if self._baumgarte is None or self._baumgarte[0] is not self.gains:
            self._baumgarte = (self.gains, BaumgarteGains(self.gains.alpha, self.gains.beta))
        return self._baumgarte[1]
