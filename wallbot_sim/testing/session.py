"""A controller under test and the graph around it, as processes of one session: started in a domain of their own,
advanced to simulation times, told faults, stopped, every process ended whatever happened.

The graph is ``graph_description.describe_tested_graph``'s: the dynamics steps only once the controller has answered
the state it waits on (strict lockstep at factor 0), so a run is the same whatever the machine's load, and it stops
at the simulation time it is advanced to (its ``stop_at``, which a fault injected there then meets exactly).

The controller is any executable. It gets in its environment ROS_DOMAIN_ID (and localhost discovery), WALLBOT_NAMESPACE
(its robot's namespace), WALLBOT_DRIVE (what it publishes) and WALLBOT_CONTROL_RATE_HZ (the states it answers, one
command each, on control_odom; through the joint bridge, joint_states), and the directory of the Python that runs the
test first on PATH (``python3`` there is this environment's).
"""

from __future__ import annotations

import os
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Mapping

from wallbot_msgs_py import topics
from wallbot_sim.domain import DomainClaim, claim_domain_id
from wallbot_sim.graph import Graph, NodeSpec
from wallbot_sim.graph_description import DYNAMICS_RECORDER, describe_tested_graph
from wallbot_sim.loop.faults import ScheduledFault, schedule_text
from wallbot_sim.settings.dynamics import DYNAMICS
from wallbot_sim.testing.errors import ControllerWouldNotStart, SpecError
from wallbot_sim.testing.expectations import Ending
from wallbot_sim.testing.spec import DROPS, Spec

CONTROLLER = 'controller'
"""The controller under test's name among the session's processes (its log: logs/controller.log)."""
RECORDER_TIMEOUT = 30.0
"""Wall seconds for the recorder to come up."""
STALL = 60.0
"""Wall seconds without simulation progress after which a session gives up (beyond start_timeout at the start):
the strict lockstep ends a run whose controller does not answer long before."""
FINAL_WAIT = 10.0
"""Wall seconds to wait at the end for the controller's answer to the last state and the last reference pose."""
STOP_TIMEOUT = 10.0
"""Wall seconds each process has to exit after its signal before it is killed."""
STEP = 1.0 / DYNAMICS['rate_hz'].default
EPSILON = 1e-9


class RunFailed(Exception):
    """The run ended before the time it was advanced to: the controller did not answer, or exited; a node died; the
    robot left the wall (``detached``) or the simulation diverged (the one-line reason)."""

    def __init__(self, reason: str, detached: bool = False) -> None:
        super().__init__(reason)
        self.detached = detached

    def ending(self, t: float) -> Ending:
        """The run's ending, at simulation time ``t``."""
        return Ending(t, str(self), self.detached)


@dataclass(frozen=True)
class RobotState:
    """The simulated robot's state where the dynamics stands (SI units, wall frame)."""

    t: float
    x: float
    y: float
    theta: float
    vx: float
    vy: float
    omega: float
    motor_torque: tuple[float, float]
    """The side torques the motors delivered in the step that reached this state (N m)."""


class Session:
    """One run of ``spec`` with its controller: ``start`` it, ``advance`` it, ``inject`` faults, ``close`` it (always:
    every process ends, the domain is freed). Output in ``out``: the bag (``out/bag``) and each process's log
    (``out/logs``). ``ground_truth``: the exact state on ground_truth/odom too (a fault injected later may silence
    odom)."""

    def __init__(self, spec: Spec, out: Path, progress: Callable[[float], None] | None = None,
                 ground_truth: bool = False) -> None:
        self.spec, self.out, self.progress = spec, Path(out), progress
        self.ground_truth = ground_truth or any(value is True and name == DROPS['odom']
                                                for fault in spec.faults for name, value in fault.changes)
        """Whether the dynamics publishes the exact state on ground_truth/odom: asked, or odom silenced by a fault, so
        that the bag keeps every state."""
        self.bag = self.out / 'bag'
        if self.bag.exists():
            raise SpecError(f'{self.bag} exists already: choose another output directory')
        self.claim: DomainClaim | None = claim_domain_id()
        self.graph = Graph(self.out / 'logs', {**self.claim.env(), 'PYTHONUNBUFFERED': '1'}, stop_timeout=STOP_TIMEOUT)
        self.monitor = None
        self.stop_at = 0.0
        self.started = False
        """Whether the run has begun (its first state recorded)."""
        self.applied: list[ScheduledFault] = list(spec.faults)
        """The faults of the run: the spec's and those injected, each from its simulation time."""
        self.pending: list[ScheduledFault] = []
        """Faults injected for a later time, applied when the run gets there."""
        self.closed = False

    # --- start ---------------------------------------------------------------------------------
    def start(self, stop_at: float) -> None:
        """Start the graph, then the controller, and wait until the run has begun; it runs to ``stop_at`` (s).
        ControllerWouldNotStart if the controller cannot be started or exits first; RunFailed if the run ends
        before it begins (the controller never answered the first state)."""
        from wallbot_sim.graph_monitor import Monitor
        self.stop_at = stop_at
        specs = self._describe(stop_at)
        self.graph.start_node(specs[0])
        self.monitor = Monitor(domain_id=self.claim.domain_id)
        self._wait(self.monitor.recorder_ready, RECORDER_TIMEOUT, 'the recorder did not come up')
        for spec in specs[1:]:
            self.graph.start_node(spec)
        if self.spec.loaded_scenario() is not None:
            # before the run moves the reference on: a short run under a controller that needs no plan could otherwise
            # end before the trajectory node has heard the recorder (seen: a 0.4 s run's bag without its reference)
            self._wait(self.monitor.reference_planned, RECORDER_TIMEOUT, 'the trajectory node did not come up')
        self._start_controller()
        self._wait(lambda: self.monitor.recorded >= 0.0, self.spec.start_timeout + STALL,
                   'the run did not begin')
        self.started = True

    def _describe(self, stop_at: float) -> list[NodeSpec]:
        spec = self.spec
        return describe_tested_graph(spec.loaded_scenario(), spec.drive, spec.control_steps, stop_at=stop_at,
                                     bag=self.bag.resolve(), robot_file=spec.robot, contact_model=spec.contact,
                                     adhesion_force=spec.adhesion_force, controller_timeout=spec.controller_timeout,
                                     start_timeout=spec.start_timeout, fault_schedule=schedule_text(spec.faults),
                                     ground_truth=self.ground_truth, world_file=spec.world, engine=spec.engine)

    def controller_env(self) -> dict[str, str]:
        """What the controller finds in its environment besides the domain (the module's docstring)."""
        here = os.path.dirname(sys.executable)
        return {'WALLBOT_NAMESPACE': topics.NAMESPACE, 'WALLBOT_DRIVE': self.spec.drive,
                'WALLBOT_CONTROL_RATE_HZ': str(self.spec.rate),
                'PATH': here + os.pathsep + os.environ.get('PATH', '')}

    def _start_controller(self) -> None:
        command = self.spec.controller
        try:
            self.graph.start(command, CONTROLLER, env=self.controller_env())
        except OSError as error:
            raise ControllerWouldNotStart(f'cannot start the controller {command[0]!r}: {error.strerror}') from None

    # --- advance ---------------------------------------------------------------------------------
    def advance(self, until: float) -> None:
        """Run to simulation time ``until`` (s) and hold there, applying the faults injected for times on the way
        where they are due; RunFailed if the run ends first."""
        while True:
            due = sorted((fault for fault in self.pending if fault.at <= until + EPSILON), key=lambda f: f.at)
            target = due[0].at if due else until
            self._run_to(target)
            if due:
                self.pending.remove(due[0])
                self.inject(dict(due[0].changes))
            if target >= until - EPSILON:
                return

    def _run_to(self, until: float) -> None:
        if until > self.stop_at + EPSILON:
            self.stop_at = until
            self.monitor.set_dynamics_parameters({'stop_at': float(until)})
        self._wait(lambda: self.monitor.recorded >= until - 0.5 * STEP and self.monitor.dynamics_stopped()
                   and self._held_at(until), STALL,
                   f'no simulation progress at t = {max(self.monitor.recorded, 0.0):.3f} s', progress=True)

    def _held_at(self, until: float) -> bool:
        """Whether the snapshot the dynamics publishes where a stop holds it has arrived (its own topic: it may
        come after the diagnostics that say it stopped)."""
        snapshot = self.monitor.snapshot
        return snapshot is not None and snapshot.t >= until - 0.5 * STEP

    def inject(self, changes: Mapping[str, object], at: float | None = None) -> None:
        """Set the dynamics' fault settings ``changes`` now (at the time the run stands at), as ``ros2 param set``
        does; ``at`` later: when the run gets there (``advance`` stops there first)."""
        now = self.now
        at = now if at is None else at
        if at < now - EPSILON:
            raise SpecError(f'a fault at {at:g} s is in the past: the run stands at {now:g} s')
        fault = ScheduledFault(at, tuple(changes.items()))
        if at > now + EPSILON:
            self.pending.append(fault)
            return
        self.monitor.set_dynamics_parameters(dict(changes))
        self.applied.append(fault)

    @property
    def now(self) -> float:
        """The simulation time the run stands at (s)."""
        return max(self.monitor.recorded, 0.0) if self.monitor is not None else 0.0

    @property
    def state(self) -> RobotState | None:
        """The newest state the dynamics published as a snapshot (at a stop: the state it stands at)."""
        snapshot = self.monitor.snapshot if self.monitor is not None else None
        if snapshot is None:
            return None
        return RobotState(snapshot.t, *snapshot.q[:3], *snapshot.qd[:3], snapshot.motor_torque)

    # --- waits and failures -----------------------------------------------------------------------
    def _wait(self, done: Callable[[], bool], stall: float, what: str, progress: bool = False) -> None:
        """Spin the monitor until ``done``; RunFailed (or ControllerWouldNotStart) when the run ends, or when the
        simulation makes no progress for ``stall`` wall seconds."""
        moved, last = time.monotonic(), self.monitor.recorded
        while not done():
            self._check()
            self.monitor.spin(0.05)
            if self.monitor.recorded != last:
                moved, last = time.monotonic(), self.monitor.recorded
                if progress and self.progress is not None:
                    self.progress(last)
            elif time.monotonic() - moved > stall:
                raise RunFailed(f'{what} within {stall:.0f} s (wall); logs in {self.graph.log_dir}')

    def _check(self) -> None:
        """Raise what ended the run, if it has ended."""
        for name, process in self.graph.processes.items():
            status = process.poll()
            if status is None:
                continue
            log = self.graph.log(name)
            if name == CONTROLLER:
                if not self.started:
                    raise ControllerWouldNotStart(f'the controller exited with status {status} before the run began; '
                                                  f'its log: {log}{last_line(log)}')
                raise RunFailed(f'the controller exited with status {status} at t = {self.now:.3f} s; its log: '
                                f'{log}{last_line(log)}')
            if name == DYNAMICS_RECORDER:
                reason = self._given_up()
                if reason is not None:
                    raise RunFailed(reason)
            raise RunFailed(f'node {name} exited with status {status} at t = {self.now:.3f} s; its log: {log}')
        status = self.monitor.status
        if status.startswith(('detached', 'diverged')):
            raise RunFailed(f'the simulation {status} at t = {self.now:.3f} s', detached=status.startswith('detached'))

    def _given_up(self) -> str | None:
        """Why the dynamics gave up (the controller did not come up or did not answer), from its last diagnostics,
        which it sends before it exits; None if it did not."""
        deadline = time.monotonic() + 2.0
        while not self.monitor.status.startswith('gave up') and time.monotonic() < deadline:
            self.monitor.spin(0.05)
        status = self.monitor.status
        if not status.startswith('gave up: '):
            return None
        reason = status.removeprefix('gave up: ')
        limit = (f'controller_timeout {self.spec.controller_timeout:g} s' if 'lockstep_timeout' in reason
                 else f'start_timeout {self.spec.start_timeout:g} s')
        return f'the controller did not answer: {reason.split(" within ")[0]} within {limit} (wall)'

    # --- the end ---------------------------------------------------------------------------------
    def finish(self) -> None:
        """Wait for what the run's last state brings (the controller's answer to it, the last reference pose), so
        that every run of a spec records the same messages."""
        end = self.now
        waits = []
        if self._answer_awaited(end):
            waits.append((lambda: self._answered(end), f'the controller did not answer the last state, at t = {end:.3f} s,'))
        if self.spec.loaded_scenario() is not None:
            waits.append((lambda: self.monitor.reference_reached(end), 'the last reference pose did not come'))
        for done, missing in waits:
            self._wait(done, FINAL_WAIT, missing)

    def _answer_awaited(self, t: float) -> bool:
        """Whether the state at ``t`` went to the controller and waits for its answer: a control instant its sensor
        carried (no dropout in force)."""
        steps = round(t / STEP)
        if steps % self.spec.control_steps:
            return False
        sensor = DROPS['wheel_states' if self.spec.drive == 'joint_commands' else 'odom']
        silent = False
        for fault in sorted(self.applied, key=lambda fault: fault.at):
            if fault.at < t - 0.5 * STEP:
                silent = dict(fault.changes).get(sensor, silent)
        return not silent

    def _answered(self, t: float) -> bool:
        snapshot = self.monitor.snapshot
        return snapshot is not None and snapshot.command is not None and snapshot.command_since >= t - 0.5 * STEP

    def close(self) -> Path:
        """End every process (the controller first, the recorder last, closing the bag: repaired if it could not),
        free the domain; the bag's path. Safe to call again."""
        if not self.closed:
            self.closed = True
            try:
                if self.monitor is not None:
                    self.monitor.close()  # before the nodes leave DDS (see cli.run.run_graph)
            finally:
                try:
                    self.graph.stop_all(first=(CONTROLLER,), last=(DYNAMICS_RECORDER,))
                finally:
                    self.claim.release()
                    from wallbot_sim.bag.reindex import repair_unclosed
                    repair_unclosed(self.bag)
        return self.bag

    def pids(self) -> dict[str, int]:
        """The process id of each process the session started, by name."""
        return {name: process.pid for name, process in self.graph.processes.items()}


def last_line(log: Path) -> str:
    """': ' and the last line a process wrote ('' if none)."""
    try:
        lines = log.read_text(errors='replace').strip().splitlines()
    except OSError:
        return ''
    return f': {lines[-1].strip()}' if lines else ''

