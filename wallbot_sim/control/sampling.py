"""The example controller as a sampled loop: which states it acts on, and the command it sends.

ROS-free. ``tracking_controller_node`` runs it on the odometry it receives; ``wallbot-sim simulate
--controller`` runs it on the model's own states. Both give it the planar state an odometry
message carries, so the headless closed loop is the graph's lockstep loop.

Timing is simulation time: the controller acts on the first state stamped at or after each
multiple of the control period (every 40th step of the 1 kHz dynamics at the default 25 Hz).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import Enum
from typing import Callable

import numpy as np

from wallbot_msgs_py.codec import PlanarState, to_nanoseconds
from wallbot_sim.control.tracking import TrackingController
from wallbot_sim.model import DEFAULT_STEP, DOF, ModelError, Robot, RobotParameters, Simulation, StepOutputs

CONTROL_RATE_HZ = 25
"""The controller's default rate (Hz of simulation time). Its feedback is slow against it (2 alpha =
20/s, beta^2 = 100/s^2): at 200 Hz it tracks within 0.2 mm of the same (docs/controller.md) and costs eight
times the CPU, and a lockstep dynamics waits for it half as often as at 50 Hz."""
MAX_WHEEL_TORQUE = 5.0
"""Commands are clamped to +- this (N m): the dynamics' default limit."""


def steps_per_period(rate_hz: int, step: float = DEFAULT_STEP) -> int:
    """Dynamics steps of ``step`` seconds in one period of a loop at ``rate_hz`` of simulation time
    (what a lockstep dynamics waits on: 40 for the tracking controller's 25 Hz at 1 kHz)."""
    return round(1.0 / (rate_hz * step))


def controller_robot(params: RobotParameters, mass_scale: float) -> Robot:
    """The controller's copy of the robot: ``params`` with the body mass scaled (a model mismatch)."""
    return Robot(params.replace(body_mass=params.body_mass * mass_scale))


class Rewind(Enum):
    """What a state stamped earlier than the last one means."""

    RESTART = 'restart'
    """Back into the first control period: a reset or a fresh dynamics; the integral is cleared."""
    RESUME = 'resume'
    """Back less far: a dynamics resumed after a kill, publishing states again; the loop carries on."""


@dataclass(frozen=True)
class TorqueCommand:
    """The torques to send (N m), clamped to the limit, and what the controller asked for."""

    tau_left: float
    tau_right: float
    requested: tuple[float, float]

    @property
    def clamped(self) -> bool:
        return (self.tau_left, self.tau_right) != self.requested


class ControlInstants:
    """Which states a controller sampled at ``rate_hz`` of simulation time acts on.

    It acts on the first state stamped at or after each multiple of the period. A stamp earlier
    than the last one is a rewind: back into the first period is a restart (a reset or a fresh
    dynamics), back less far a dynamics resumed after a kill, acting again from the next instant.
    """

    def __init__(self, rate_hz: int) -> None:
        self.rate_hz = rate_hz
        self.next_due_ns: int | None = None
        self.last_stamp_ns: int | None = None

    @property
    def period_ns(self) -> int:
        return round(1e9 / self.rate_hz)

    def set_rate(self, rate_hz: int) -> None:
        """A new control rate: act on the next state."""
        self.rate_hz, self.next_due_ns = rate_hz, None

    def observe(self, stamp_ns: int) -> Rewind | None:
        """Note the stamp of a state as it arrives; if time went back, say how far."""
        rewind = None
        if self.last_stamp_ns is not None and stamp_ns < self.last_stamp_ns:
            if stamp_ns < self.period_ns:
                rewind = Rewind.RESTART
                self.next_due_ns = None
            else:
                rewind = Rewind.RESUME
                self.next_due_ns = -(-stamp_ns // self.period_ns) * self.period_ns
        self.last_stamp_ns = stamp_ns
        return rewind

    def due(self, stamp_ns: int) -> bool:
        """Whether the state stamped ``stamp_ns`` is one the controller acts on."""
        return self.next_due_ns is None or stamp_ns >= self.next_due_ns

    def acted(self, stamp_ns: int) -> None:
        """The state stamped ``stamp_ns`` was acted on: the next is due one period on."""
        period = self.period_ns
        self.next_due_ns = (stamp_ns // period + 1) * period


class SampledController:
    """A TrackingController acting at ``rate_hz`` of simulation time on planar states."""

    def __init__(self, controller: TrackingController, rate_hz: int = CONTROL_RATE_HZ,
                 max_wheel_torque: float = MAX_WHEEL_TORQUE) -> None:
        self.controller = controller
        self.instants = ControlInstants(rate_hz)
        self.max_wheel_torque = max_wheel_torque

    @property
    def period_ns(self) -> int:
        return self.instants.period_ns

    def set_rate(self, rate_hz: int) -> None:
        """A new control rate: act on the next state."""
        self.instants.set_rate(rate_hz)

    def observe(self, stamp_ns: int) -> Rewind | None:
        """Note the stamp of a state as it arrives; if time went back, say how far (and act on it)."""
        rewind = self.instants.observe(stamp_ns)
        if rewind is Rewind.RESTART:
            self.controller.reset()
        return rewind

    def due(self, stamp_ns: int) -> bool:
        """Whether the state stamped ``stamp_ns`` is one the controller acts on."""
        return self.instants.due(stamp_ns)

    def command(self, state: PlanarState) -> TorqueCommand:
        """The torques for the state (taken as acted on: the next is due one period on).

        The wheels' spin rates are their rolling values (the driven robot's wheels roll on the
        wall), so a state as odometry carries it is enough. ModelError if the torques are not finite.
        """
        self.instants.acted(state.stamp_ns)
        period = self.period_ns
        robot = self.controller.robot
        q, qd = np.zeros(DOF), np.zeros(DOF)
        q[:3] = state.x, state.y, state.theta
        qd[:3] = state.xd, state.yd, state.thd
        qd[3:] = robot.rolling_spin_rates(state.theta, (state.xd, state.yd), state.thd)
        command = self.controller.update(state.t, q, qd, period * 1e-9)
        requested = (float(command.tau_left), float(command.tau_right))
        if not all(math.isfinite(tau) for tau in requested):
            raise ModelError(f'non-finite torques {requested} at t = {state.t:.3f} s')
        limit = self.max_wheel_torque
        left, right = (min(limit, max(-limit, tau)) for tau in requested)
        return TorqueCommand(left, right, requested)


def odometry_state(out: StepOutputs) -> PlanarState:
    """The planar state the dynamics' odometry carries for the outputs of a step."""
    x, y, theta = out.q[:3].tolist()
    xd, yd, thd = out.qd[:3].tolist()
    return PlanarState(to_nanoseconds(out.t), x, y, math.atan2(math.sin(theta), math.cos(theta)), xd, yd, thd)


def close_loop(simulation: Simulation, loop: SampledController,
               on_command: Callable[[float, TorqueCommand], None] | None = None) -> Callable[[StepOutputs], None]:
    """A step hook that closes the loop as the graph's lockstep does (no DDS).

    Called with the outputs of each instant after they were used (published, written), it hands
    the controller the states it acts on and holds its command from the next step on, as the
    dynamics node does with the controller's answer to the state it published. ``on_command`` is
    given each command sent, with the time of the state it answers (what the graph's controller
    publishes on wheel_torque_cmd).
    """
    def answer(out: StepOutputs) -> None:
        stamp_ns = to_nanoseconds(out.t)
        loop.observe(stamp_ns)
        if loop.due(stamp_ns):
            command = loop.command(odometry_state(out))
            simulation.set_motor_torque(command.tau_left, command.tau_right)
            if on_command is not None:
                on_command(out.t, command)
    return answer
