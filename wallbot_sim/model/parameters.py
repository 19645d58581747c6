"""Robot parameters (docs/model.md section 2) and their validation."""

from __future__ import annotations

from dataclasses import asdict, dataclass, fields
from typing import Any, Mapping

from wallbot_sim.model.errors import ParameterError
from wallbot_sim.model.keys import check_keys
from wallbot_sim.model.motor import MotorParameters
from wallbot_sim.model.numbers import FINITE, NON_NEGATIVE, POSITIVE
from wallbot_sim.model.sensors import SensorParameters
from wallbot_sim.model.vacuum import VacuumParameters

_POSITIVE = (
    'body_mass', 'wheel_mass', 'body_yaw_inertia', 'wheel_yaw_inertia', 'wheel_spin_inertia',
    'wheel_radius', 'half_wheelbase', 'half_track', 'com_height', 'wall_friction', 'gravity',
    'adsorption_safety', 'velocity_epsilon', 'baumgarte_alpha', 'baumgarte_beta', 'kinetic_friction',
    'stick_velocity',
)
_NON_NEGATIVE = ('rolling_resistance',)
PYTHON_ONLY_BLOCKS = ('motor', 'adhesion')
"""The blocks that change the dynamics, which only the Python model computes (docs/model.md 13)."""
OPTIONAL_BLOCKS = (*PYTHON_ONLY_BLOCKS, 'sensors')
"""The robot file's blocks it may leave out (docs/model.md 13)."""
UNITS = {
    'body_mass': 'kg', 'wheel_mass': 'kg', 'body_yaw_inertia': 'kg m^2', 'wheel_yaw_inertia': 'kg m^2',
    'wheel_spin_inertia': 'kg m^2', 'wheel_radius': 'm', 'half_wheelbase': 'm', 'half_track': 'm', 'com_offset': 'm',
    'com_height': 'm', 'wall_friction': '-', 'rolling_resistance': '-', 'gravity': 'm/s^2', 'adsorption_safety': '-',
    'velocity_epsilon': 'm/s', 'baumgarte_alpha': '1/s', 'baumgarte_beta': '1/s', 'kinetic_friction': '-',
    'adhesion_force': 'N', 'stick_velocity': 'm/s',
}
"""The unit of each parameter (config/robot.yaml's comments); '-' a ratio."""


@dataclass(frozen=True)
class RobotParameters:
    """Physical parameters of the robot; names are the keys of ``config/robot.yaml``."""

    body_mass: float = 8.0
    wheel_mass: float = 0.25
    body_yaw_inertia: float = 0.10
    wheel_yaw_inertia: float = 1.0e-4
    wheel_spin_inertia: float = 2.0e-4
    wheel_radius: float = 0.04
    half_wheelbase: float = 0.10
    half_track: float = 0.12
    com_offset: tuple[float, float] = (0.0, 0.0)
    com_height: float = 0.05
    wall_friction: float = 0.7
    rolling_resistance: float = 0.03
    gravity: float = 9.81
    adsorption_safety: float = 1.5
    velocity_epsilon: float = 1.0e-3
    baumgarte_alpha: float = 5.0
    baumgarte_beta: float = 5.0
    kinetic_friction: float = 0.6
    adhesion_force: float | None = None
    """F_ad (N); None applies k_ad F_min (section 3)."""
    stick_velocity: float = 1.0e-3
    motor: MotorParameters | None = None
    """The optional ``motor`` block (docs/model.md 13.2); None: any commanded torque is applied."""
    adhesion: VacuumParameters | None = None
    """The optional ``adhesion`` block, a vacuum chamber (docs/model.md 13.3); None: F_ad is constant."""
    sensors: SensorParameters | None = None
    """The optional ``sensors`` block (docs/model.md 13.5); None: the graph publishes no sensor of its own."""

    def __post_init__(self) -> None:
        for name in _POSITIVE + _NON_NEGATIVE:
            allowed = POSITIVE if name in _POSITIVE else NON_NEGATIVE
            object.__setattr__(self, name, allowed.check(name, getattr(self, name)))
        if self.kinetic_friction > self.wall_friction:
            raise ParameterError(f'kinetic_friction must be <= wall_friction ({self.wall_friction!r}), '
                                 f'got {self.kinetic_friction!r}')
        if self.adhesion_force is not None:  # null applies k_ad F_min
            object.__setattr__(self, 'adhesion_force', POSITIVE.check('adhesion_force', self.adhesion_force))
        for block, kind in (('motor', MotorParameters), ('adhesion', VacuumParameters), ('sensors', SensorParameters)):
            if isinstance(getattr(self, block), Mapping):  # a parsed block, or ``replace``'s copy of one
                object.__setattr__(self, block, kind.from_mapping(getattr(self, block)))
        if self.sensors is not None and self.sensors.pressure is not None and self.adhesion is None:
            raise ParameterError('sensors pressure measures the vacuum chamber: the robot file has no adhesion block')
        offset = self.com_offset
        if isinstance(offset, (str, bytes)) or not hasattr(offset, '__len__') or len(offset) != 2:
            raise ParameterError(f'com_offset must be a pair [c_x, c_y], got {offset!r}')
        object.__setattr__(
            self, 'com_offset', (FINITE.check('com_offset', offset[0]), FINITE.check('com_offset', offset[1])))

    @classmethod
    def from_mapping(cls, values: Mapping[str, Any]) -> RobotParameters:
        """Build from a mapping (a parsed YAML file); every field is required, no key is unknown."""
        if not isinstance(values, Mapping):
            raise ParameterError(f'robot parameters must be a mapping of names to values, got {values!r}')
        known = {f.name for f in fields(cls)}
        check_keys(values, known, 'robot parameter')
        missing = sorted(known - set(values) - set(OPTIONAL_BLOCKS))
        if missing:
            raise ParameterError(f'missing robot parameter {missing[0]!r}')
        return cls(**values)

    def replace(self, **changes: Any) -> RobotParameters:
        """A copy with some values changed (validated like any other)."""
        return RobotParameters(**{**asdict(self), **changes})
