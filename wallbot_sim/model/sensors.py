"""The robot file's optional ``sensors`` block (docs/model.md 13.5): which sensors the robot has, and how they err.

The block only describes the sensors; what they measure of a step's state is ``wallbot_sim.sensors``. A sensor
the block leaves out (or sets to null) is not simulated; every key of a sensor it names is optional (its default
below), so ``imu: {}`` is an exact IMU at 200 Hz.
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Any, Mapping

from wallbot_sim.model.errors import ParameterError
from wallbot_sim.model.keys import check_keys
from wallbot_sim.model.numbers import NON_NEGATIVE, NumberRange

RATE = NumberRange(0.0, 100_000.0, low_open=True)
"""A sensor's samples per second of simulation time (at most one per published step)."""
SEED = NumberRange(0, 2**31 - 1)
COUNTS = NumberRange(1, 2**31 - 1)
BIAS = NumberRange(-1e6, 1e6)


def _checked(block: Any, ranges: Mapping[str, NumberRange], where: str, integers: tuple[str, ...] = ()) -> None:
    """Check and normalize each field of the frozen dataclass ``block`` against its range (ParameterError naming
    ``where`` and the key); ``integers`` must be whole numbers."""
    for name, allowed in ranges.items():
        value = getattr(block, name)
        number = allowed.check(f'{where} {name}', value)
        if name in integers:
            if number != int(number):
                raise ParameterError(f'{where} {name} must be a whole number, got {value!r}')
            number = int(number)
        object.__setattr__(block, name, number)


def _block(kind: type, values: Any, where: str) -> Any:
    """``kind`` from a block of the file (an empty mapping: every default); unknown keys are refused."""
    check_keys(values, [field.name for field in fields(kind)], f'{where} key')
    return kind(**values)


@dataclass(frozen=True)
class ImuParameters:
    """``sensors.imu``: an accelerometer and a gyroscope at the centre, in base_link's axes. White noise of a
    density per axis and a bias that random-walks from 0 (the Allan-variance figures of a datasheet)."""

    rate: float = 200.0
    """Samples per second of simulation time."""
    accelerometer_noise_density: float = 0.0
    """m/s^2/sqrt(Hz): a sample's white noise has the standard deviation density sqrt(rate)."""
    accelerometer_random_walk: float = 0.0
    """m/s^3/sqrt(Hz): the bias changes by a Gaussian of standard deviation walk / sqrt(rate) per sample."""
    gyroscope_noise_density: float = 0.0
    """rad/s/sqrt(Hz)."""
    gyroscope_random_walk: float = 0.0
    """rad/s^2/sqrt(Hz)."""
    seed: int = 0

    def __post_init__(self) -> None:
        _checked(self, {'rate': RATE, 'accelerometer_noise_density': NON_NEGATIVE,
                        'accelerometer_random_walk': NON_NEGATIVE, 'gyroscope_noise_density': NON_NEGATIVE,
                        'gyroscope_random_walk': NON_NEGATIVE, 'seed': SEED}, 'sensors imu', ('seed',))


@dataclass(frozen=True)
class EncoderParameters:
    """``sensors.encoders``: an incremental encoder on each wheel, its count read ``rate`` times a second."""

    rate: float = 100.0
    counts_per_rev: int = 4096
    """Counts per wheel revolution: the angle is known to 2 pi / counts_per_rev."""

    def __post_init__(self) -> None:
        _checked(self, {'rate': RATE, 'counts_per_rev': COUNTS}, 'sensors encoders', ('counts_per_rev',))


@dataclass(frozen=True)
class PressureParameters:
    """``sensors.pressure``: an absolute pressure sensor in the vacuum chamber (the ``adhesion`` block's)."""

    rate: float = 50.0
    noise: float = 0.0
    """Standard deviation of a sample's Gaussian noise (Pa)."""
    bias: float = 0.0
    """A constant offset of every sample (Pa)."""
    seed: int = 0

    def __post_init__(self) -> None:
        _checked(self, {'rate': RATE, 'noise': NON_NEGATIVE, 'bias': BIAS, 'seed': SEED}, 'sensors pressure',
                 ('seed',))


SENSOR_KINDS = {'imu': ImuParameters, 'encoders': EncoderParameters, 'pressure': PressureParameters}


@dataclass(frozen=True)
class SensorParameters:
    """The ``sensors`` block: each sensor the robot has, None for one it has not."""

    imu: ImuParameters | None = None
    encoders: EncoderParameters | None = None
    pressure: PressureParameters | None = None

    def __post_init__(self) -> None:
        for name, kind in SENSOR_KINDS.items():
            value = getattr(self, name)
            if value is not None and not isinstance(value, kind):  # a parsed block, or ``replace``'s copy of one
                object.__setattr__(self, name, _block(kind, value, f'sensors {name}'))

    @classmethod
    def from_mapping(cls, values: Any) -> SensorParameters:
        check_keys(values, SENSOR_KINDS, 'sensors key')
        return cls(**values)
