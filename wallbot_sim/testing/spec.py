"""A controller test, read from YAML (``wallbot-sim test SPEC.yaml``) or given to the pytest fixture:

    scenario: circle              # circle, figure8, rest (at rest at the origin, no reference) or a scenario file
    robot: my_robot.yaml          # optional: the robot file (default: the installed one)
    world: my_world.yaml          # optional: the world file (inclination, patches, seams; default: a vertical wall)
    contact: coulomb              # ideal (default) or coulomb
    duration: 3.0                 # simulated seconds (default: the scenario's; rest needs one)
    drive: wheel_torque_cmd       # what the controller publishes: wheel_torque_cmd, cmd_vel or joint_commands
    controller: python3 my_controller.py --ros-args -p gain:=2.0   # a command line, or a list of arguments
    control_rate: 25              # Hz of simulation time: the states the controller answers, one command each
    controller_timeout: 5.0       # wall seconds an answer may take; longer fails the run
    start_timeout: 30.0           # wall seconds for the controller to come up and answer the first state
    adhesion_force: 250.0         # optional, N (default: the robot file's)
    faults:                       # optional, at simulation times
      - {at: 1.0, motor_left: 0.0}                 # the left motor delivers 0 % of its torque from 1 s
      - {at: 1.5, for: 0.5, adhesion_scale: 0.6}   # 60 % adhesion for 0.5 s
      - {at: 2.0, for: 0.2, drop: odom}            # odom (and control_odom) silent for 0.2 s (or wheel_states, imu)
    expect:
      max_tracking_error_after: {t: 2.0, m: 0.01}  # after t s, the centre within m metres of the reference
      no_slip: true                # no wheel slips (coulomb), no friction use above 1 (ideal)
      no_detachment: true          # every normal load stays >= 0
      min_adhesion_margin: 1.1     # applied / least-needed adhesion force, least over the run (``motors``)
      max_motor_torque: 2.5        # N m per side, delivered by the motors

Every key is checked as the other input files' are: an unknown one is refused naming the closest known one, a bad
value in one line naming the key. Relative file paths (scenario, robot, world) are relative to the spec's folder;
the controller command runs in the current directory. A world file, or a robot file's motor or adhesion block, runs
the dynamics on the python engine (docs/model.md 13).
"""

from __future__ import annotations

import math
import shlex
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Mapping, Sequence

from wallbot_sim.config import load_robot_parameters, load_scenario, load_world, read_yaml
from wallbot_sim.control.sampling import CONTROL_RATE_HZ, steps_per_period
from wallbot_sim.control.wheel_speed import SPEED_LOOP_RATE_HZ
from wallbot_sim.loop.faults import ScheduledFault
from wallbot_sim.model import ParameterError, Robot, Scenario
from wallbot_sim.model.contact import CONTACT_MODELS, IDEAL
from wallbot_sim.model.keys import unknown_key
from wallbot_sim.model.numbers import NumberRange
from wallbot_sim.model.python_only import python_only_features
from wallbot_sim.model.scenario import SHAPES
from wallbot_sim.model.simulation import NUMBA, PYTHON
from wallbot_sim.settings.dynamics import DYNAMICS
from wallbot_sim.testing.errors import SpecError

REST = 'rest'
"""The scenario without a reference: at rest at the origin, facing +X."""
DRIVES = {'wheel_torque_cmd': CONTROL_RATE_HZ, 'cmd_vel': SPEED_LOOP_RATE_HZ, 'joint_commands': SPEED_LOOP_RATE_HZ}
"""What the controller under test may publish, and the default control rate (Hz) of each."""
KEYS = ('scenario', 'robot', 'world', 'contact', 'duration', 'drive', 'controller', 'control_rate',
        'controller_timeout', 'start_timeout', 'adhesion_force', 'faults', 'expect')
FAULT_KEYS = ('at', 'for', 'motor_left', 'motor_right', 'adhesion_scale', 'drop')
FAULT_SETTINGS = {'motor_left': 'motor_efficiency_left', 'motor_right': 'motor_efficiency_right',
                  'adhesion_scale': 'adhesion_scale'}
"""A fault's key and the dynamics setting it sets (``drop`` sets the dropout setting of its topic)."""
DROPS = {'odom': 'drop_odom', 'wheel_states': 'drop_wheel_states', 'imu': 'drop_imu'}
"""The sensor topics a fault may silence, and the dynamics setting that does."""
EXPECTATIONS = ('max_tracking_error_after', 'no_slip', 'no_detachment', 'min_adhesion_margin', 'max_motor_torque')
DURATION = NumberRange(0.0, 1e6, low_open=True)
TIMEOUT = DYNAMICS['lockstep_timeout'].allowed
START_TIMEOUT = NumberRange(1.0, 3600.0)
POSITIVE = NumberRange(0.0, 1e9, low_open=True)
TIME = NumberRange(0.0, 1e9)


@dataclass(frozen=True)
class Expectations:
    """What a run must show; None or False: not checked."""

    max_tracking_error_after: tuple[float, float] | None = None
    """(t, m): after t seconds the centre stays within m metres of the reference."""
    no_slip: bool = False
    no_detachment: bool = False
    min_adhesion_margin: float | None = None
    max_motor_torque: float | None = None
    """N m per side."""

    def names(self) -> tuple[str, ...]:
        """The expectations checked, in the order of EXPECTATIONS."""
        return tuple(name for name in EXPECTATIONS if getattr(self, name) not in (None, False))


@dataclass(frozen=True)
class Spec:
    """A controller test: the run, the controller under test, the faults, the expectations."""

    controller: tuple[str, ...]
    scenario: str = 'circle'
    """circle, figure8, rest, or a scenario file's path."""
    robot: Path | None = None
    world: Path | None = None
    """The world file (None: a vertical, uniform wall)."""
    contact: str = IDEAL
    duration: float | None = None
    """Simulated seconds (None: the scenario's)."""
    drive: str = 'wheel_torque_cmd'
    control_rate: int | None = None
    """Hz of simulation time (None: the drive's default, DRIVES)."""
    controller_timeout: float = 5.0
    start_timeout: float = 30.0
    adhesion_force: float = 0.0
    """N; 0: the robot file's."""
    faults: tuple[ScheduledFault, ...] = ()
    """The faults as dynamics settings at simulation times (:func:`fault_schedule`)."""
    expect: Expectations = field(default_factory=Expectations)
    name: str = 'controller test'

    @property
    def rate(self) -> int:
        return self.control_rate if self.control_rate is not None else DRIVES[self.drive]

    @property
    def control_steps(self) -> int:
        """Dynamics steps per control period: every that many steps a state waits for its answer."""
        return steps_per_period(self.rate)

    @property
    def engine(self) -> str:
        """The dynamics' engine: python where the robot file's blocks or the world file need it, else numba."""
        robot = Robot(load_robot_parameters(self.robot), load_world(self.world))
        return PYTHON if python_only_features(robot) else NUMBA

    def loaded_scenario(self) -> Scenario | None:
        """The scenario (None for rest)."""
        return None if self.scenario == REST else load_scenario(self.scenario)

    def run_duration(self) -> float:
        """The simulated seconds of the run."""
        if self.duration is not None:
            return self.duration
        return self.loaded_scenario().duration


def load_spec(path: str | Path) -> Spec:
    """The spec at ``path``; SpecError naming the file and what is wrong (a YAML error: its line and column)."""
    try:
        return parse_spec(read_yaml(path), Path(path).parent, Path(path).stem)
    except ParameterError as error:  # read_yaml's own errors name the file already
        raise SpecError(str(error)) from None
    except SpecError as error:
        raise SpecError(f'{path}: {error}') from None


def parse_spec(values: Any, folder: Path = Path('.'), name: str = 'controller test') -> Spec:
    """A spec from its parsed YAML mapping; relative file paths in it are relative to ``folder``."""
    reason = unknown_key(values, KEYS, 'test spec key')
    if reason is not None:
        raise SpecError(reason)
    if 'controller' not in values:
        raise SpecError('controller is missing: the command that starts the controller under test')
    return make_spec(folder=folder, name=name, **values)


def make_spec(controller: str | Sequence[str], scenario: str = 'circle', robot: str | Path | None = None,
              world: str | Path | None = None, contact: str = IDEAL, duration: float | None = None, drive: str = 'wheel_torque_cmd',
              control_rate: int | None = None, controller_timeout: float = 5.0, start_timeout: float = 30.0,
              adhesion_force: float | None = None, faults: Sequence[Mapping[str, Any]] | None = None,
              expect: Mapping[str, Any] | None = None, folder: Path = Path('.'),
              name: str = 'controller test') -> Spec:
    """A spec from its keys' values, each checked (SpecError naming the key); the fixture's ``start`` takes the same
    keywords as a spec file's keys."""
    if not isinstance(scenario, str) or not scenario:
        raise SpecError(f'scenario must be {", ".join(SHAPES)}, {REST} or a scenario file, got {scenario!r}')
    if scenario not in (*SHAPES, REST):
        scenario = str(folder / scenario)
    robot_path = _input_file('robot', robot, folder, load_robot_parameters)
    world_path = _input_file('world', world, folder, load_world)
    if contact not in CONTACT_MODELS:
        raise SpecError(f'contact must be one of {", ".join(CONTACT_MODELS)}, got {contact!r}')
    if drive not in DRIVES:
        raise SpecError(f'drive must be one of {", ".join(DRIVES)}, got {drive!r}')
    spec = Spec(controller=_command(controller), scenario=scenario, robot=robot_path, world=world_path, contact=contact,
                duration=None if duration is None else _number('duration', duration, DURATION),
                drive=drive, control_rate=_rate(control_rate),
                controller_timeout=_number('controller_timeout', controller_timeout, TIMEOUT),
                start_timeout=_number('start_timeout', start_timeout, START_TIMEOUT),
                adhesion_force=0.0 if adhesion_force is None else _setting('adhesion_force', adhesion_force),
                faults=fault_schedule(faults or ()), expect=parse_expectations(expect or {}), name=name)
    try:
        reference = spec.loaded_scenario()
    except ParameterError as error:
        raise SpecError(f'scenario: {error}') from None
    if reference is None and duration is None:
        raise SpecError(f'duration is missing: scenario {REST} has none of its own')
    if reference is None and spec.expect.max_tracking_error_after is not None:
        raise SpecError(f'max_tracking_error_after needs a reference to track: scenario {REST} has none')
    end = spec.run_duration()
    late = [fault.at for fault in spec.faults if fault.at > end]
    if late:
        raise SpecError(f'faults: a fault at {late[0]:g} s comes after the run ends ({end:g} s)')
    return spec


def _input_file(key: str, value: Any, folder: Path, load: Callable[[Path], object]) -> Path | None:
    """The robot or world file ``value`` names (relative to ``folder``), read by ``load`` to check it; None for none."""
    if value is None:
        return None
    if not isinstance(value, (str, Path)):
        raise SpecError(f'{key} must be a {key} file path, got {value!r}')
    path = (folder / value).resolve()
    try:
        load(path)
    except ParameterError as error:
        raise SpecError(f'{key}: {error}') from None
    return path


def _command(controller: Any) -> tuple[str, ...]:
    if isinstance(controller, str):
        try:
            words = shlex.split(controller)
        except ValueError as error:
            raise SpecError(f'controller: {error} in {controller!r}') from None
    elif isinstance(controller, Sequence) and all(isinstance(word, (str, Path)) for word in controller):
        words = [str(word) for word in controller]
    else:
        words = []
    if not words:
        raise SpecError(f'controller must be a command line or a list of its words, got {controller!r}')
    return tuple(words)


def _number(key: str, value: Any, allowed: NumberRange) -> float:
    problem = allowed.problem(value)
    if problem is not None:
        raise SpecError(f'{key} {problem}')
    return float(value)


def _setting(name: str, value: Any) -> Any:
    """``value`` as the dynamics setting ``name`` takes it; SpecError in its words."""
    setting = DYNAMICS[name]
    if setting.kind is float and isinstance(value, int) and not isinstance(value, bool):
        value = float(value)
    problem = setting.problem(value)
    if problem is not None:
        raise SpecError(f'{name} {problem}')
    return value


def _rate(rate: Any) -> int | None:
    if rate is None:
        return None
    if isinstance(rate, bool) or not isinstance(rate, int) or not 1 <= rate <= 1000 or 1000 % rate:
        raise SpecError(f'control_rate must be a whole number of Hz dividing 1000 (the dynamics steps at 1 kHz), '
                        f'got {rate!r}')
    return rate


def fault_schedule(entries: Sequence[Mapping[str, Any]]) -> tuple[ScheduledFault, ...]:
    """The faults of a spec as dynamics settings at simulation times, in time order: each entry's settings at its
    ``at``, and with ``for`` back to the values they had before at ``at + for``. SpecError naming the entry for a bad
    one, or for two faults that set one setting over overlapping spans."""
    if isinstance(entries, (str, bytes, Mapping)) or not isinstance(entries, Sequence):
        raise SpecError(f'faults must be a list of faults ({{at: T, ...}}), got {entries!r}')
    scheduled, spans = [], {}
    for index, entry in enumerate(entries):
        try:
            at, until, changes = fault_entry(entry)
        except SpecError as error:
            raise SpecError(f'faults[{index}]: {error}') from None
        for name in changes:
            for other, (start, end) in spans.get(name, {}).items():
                if at < end and start < until:
                    raise SpecError(f'faults[{index}]: {name} at {at:g} s overlaps faults[{other}] ({start:g} .. '
                                    f'{end:g} s): one fault a setting at a time')
            spans.setdefault(name, {})[index] = (at, until)
        scheduled.append(ScheduledFault(at, tuple(changes.items())))
        if until < math.inf:
            scheduled.append(ScheduledFault(until, tuple(healed(changes).items())))
    return tuple(sorted(scheduled, key=lambda fault: fault.at))


def healed(changes: Mapping[str, Any]) -> dict[str, Any]:
    """The settings that end a fault of ``changes``: each back to its default (no fault)."""
    return {name: DYNAMICS[name].default for name in changes}


def fault_entry(entry: Any) -> tuple[float, float, dict[str, Any]]:
    """(at, until, the dynamics settings) of one fault: ``{at: T, for: S, motor_left: ..., ...}``; ``until`` is
    infinite without ``for``. Each setting's value is checked by the dynamics' own rule."""
    reason = unknown_key(entry, FAULT_KEYS, 'fault key')
    if reason is not None:
        raise SpecError(reason)
    if 'at' not in entry:
        raise SpecError('at is missing: the simulation time the fault begins (s)')
    at = _number('at', entry['at'], TIME)
    until = at + _number('for', entry['for'], POSITIVE) if 'for' in entry else math.inf
    changes = {setting: _setting(setting, entry[key]) for key, setting in FAULT_SETTINGS.items() if key in entry}
    if 'drop' in entry:
        if entry['drop'] not in DROPS:
            raise SpecError(f'drop must name a sensor topic ({", ".join(DROPS)}), got {entry["drop"]!r}')
        changes[DROPS[entry['drop']]] = True
    if not changes:
        raise SpecError(f'no fault is given: use {", ".join(key for key in FAULT_KEYS if key not in ("at", "for"))}')
    return at, until, changes


def parse_expectations(values: Any) -> Expectations:
    """The ``expect`` mapping; SpecError naming the expectation for a bad value."""
    reason = unknown_key(values, EXPECTATIONS, 'expectation')
    if reason is not None:
        raise SpecError(reason)
    tracking = values.get('max_tracking_error_after')
    if tracking is not None:
        reason = unknown_key(tracking, ('t', 'm'), 'max_tracking_error_after key')
        if reason is not None or set(tracking) != {'t', 'm'}:
            raise SpecError(f'max_tracking_error_after must be {{t: SECONDS, m: METRES}}, got {tracking!r}')
        tracking = (_number('max_tracking_error_after t', tracking['t'], TIME),
                    _number('max_tracking_error_after m', tracking['m'], POSITIVE))
    flags = {}
    for name in ('no_slip', 'no_detachment'):
        flag = values.get(name, False)
        if not isinstance(flag, bool):
            raise SpecError(f'{name} must be true or false, got {flag!r}')
        flags[name] = flag
    numbers = {name: None if values.get(name) is None else _number(name, values[name], POSITIVE)
               for name in ('min_adhesion_margin', 'max_motor_torque')}
    return Expectations(tracking, **flags, **numbers)
