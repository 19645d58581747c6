"""The surface the robot drives on (docs/model.md 13.1): its inclination, patches of other friction, and seams.

The wall frame keeps its axes (X across the surface, Y up the slope, Z out of it); the inclination
turns gravity: in the wall frame it is (0, -g sin i, -g cos i). Its in-plane part pulls the robot
down the slope, its out-of-plane part presses the robot on (floor, i = 0) or pulls it off
(ceiling, i = 180 degrees). A patch is a wall-frame rectangle whose friction coefficients replace
the robot file's for the wheels whose contact point lies in it; a seam is a wall-frame segment of a
given width that leaks the suction of a vacuum chamber above it (``vacuum``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from wallbot_sim.model.errors import ParameterError
from wallbot_sim.model.keys import check_block, check_keys
from wallbot_sim.model.numbers import FINITE, POSITIVE, NumberRange

INCLINATION = NumberRange(0.0, 180.0)
"""Degrees between the surface and the horizontal: 0 floor, 90 wall, 180 ceiling."""
VERTICAL = 90.0
_WORLD_KEYS = ('inclination', 'patches', 'seams')
_PATCH_KEYS = ('x', 'y', 'wall_friction', 'kinetic_friction')
_SEAM_KEYS = ('from', 'to', 'width')


@dataclass(frozen=True)
class Patch:
    """A wall-frame rectangle x_low <= X <= x_high, y_low <= Y <= y_high of other friction coefficients."""

    x: tuple[float, float]
    y: tuple[float, float]
    wall_friction: float
    kinetic_friction: float

    @classmethod
    def from_mapping(cls, values: Mapping[str, Any], where: str) -> Patch:
        check_block(values, _PATCH_KEYS, where)
        static = POSITIVE.check(f'{where} wall_friction', values['wall_friction'])
        kinetic = POSITIVE.check(f'{where} kinetic_friction', values['kinetic_friction'])
        if kinetic > static:
            raise ParameterError(f'{where} kinetic_friction must be <= its wall_friction ({static!r}), got {kinetic!r}')
        return cls(_interval(values['x'], f'{where} x'), _interval(values['y'], f'{where} y'), static, kinetic)

    def contains(self, points: np.ndarray) -> np.ndarray:
        """Whether each wall-frame point (k, 2) lies in the rectangle (k,), its edges included."""
        return ((points[:, 0] >= self.x[0]) & (points[:, 0] <= self.x[1])
                & (points[:, 1] >= self.y[0]) & (points[:, 1] <= self.y[1]))


@dataclass(frozen=True)
class Seam:
    """A straight gap of ``width`` (m) along the wall-frame segment from ``start`` to ``end``."""

    start: tuple[float, float]
    end: tuple[float, float]
    width: float

    @classmethod
    def from_mapping(cls, values: Mapping[str, Any], where: str) -> Seam:
        check_block(values, _SEAM_KEYS, where)
        start, end = _point(values['from'], f'{where} from'), _point(values['to'], f'{where} to')
        if start == end:
            raise ParameterError(f'{where} from and to must differ, got {list(start)} twice')
        return cls(start, end, POSITIVE.check(f'{where} width', values['width']))

    def length_within(self, centre: np.ndarray, radius: float) -> float:
        """The length (m) of the seam inside the disc of ``radius`` about the wall-frame point ``centre``."""
        start, end = np.array(self.start), np.array(self.end)
        span = end - start
        length = float(np.hypot(span[0], span[1]))
        along = span / length
        offset = np.asarray(centre, dtype=float) - start
        foot = float(offset @ along)
        distance_sq = float(offset @ offset) - foot * foot
        half_chord_sq = radius * radius - distance_sq
        if half_chord_sq <= 0.0:
            return 0.0
        half_chord = math.sqrt(half_chord_sq)
        return max(0.0, min(length, foot + half_chord) - max(0.0, foot - half_chord))


@dataclass(frozen=True)
class World:
    """The surface: its inclination (degrees), patches (the first one holding a point wins) and seams."""

    inclination: float = VERTICAL
    patches: tuple[Patch, ...] = ()
    seams: tuple[Seam, ...] = ()

    def __post_init__(self) -> None:
        object.__setattr__(self, 'inclination', INCLINATION.check('inclination', self.inclination))

    @classmethod
    def from_mapping(cls, values: Mapping[str, Any]) -> World:
        """Build from a parsed world file: every key optional (a vertical, uniform wall without seams)."""
        if values is None:
            return cls()
        check_keys(values, _WORLD_KEYS, 'world key')
        patches = tuple(Patch.from_mapping(patch, f'patches[{index}]')
                        for index, patch in enumerate(_sequence(values.get('patches'), 'patches')))
        seams = tuple(Seam.from_mapping(seam, f'seams[{index}]')
                      for index, seam in enumerate(_sequence(values.get('seams'), 'seams')))
        return cls(values.get('inclination', VERTICAL), patches, seams)

    @property
    def slope(self) -> tuple[float, float]:
        """(sin i, cos i), exact at multiples of 90 degrees (a vertical wall's in-plane gravity is g itself)."""
        quarter, rest = divmod(self.inclination, 90.0)
        if rest == 0.0:
            return ((0.0, 1.0), (1.0, 0.0), (0.0, -1.0))[int(quarter)]
        angle = math.radians(self.inclination)
        return math.sin(angle), math.cos(angle)

    def friction_at(self, points: np.ndarray, static: float, kinetic: float) -> tuple[np.ndarray, np.ndarray]:
        """(mu_s, mu_k) at each wall-frame point (k, 2): the first patch's holding it, else ``static``, ``kinetic``."""
        static_at, kinetic_at = np.full(len(points), static), np.full(len(points), kinetic)
        free = np.ones(len(points), dtype=bool)
        for patch in self.patches:
            inside = free & patch.contains(points)
            static_at[inside], kinetic_at[inside] = patch.wall_friction, patch.kinetic_friction
            free &= ~inside
        return static_at, kinetic_at

    def seam_area(self, centre: np.ndarray, radius: float) -> float:
        """The seams' gap area (m^2) under a disc of ``radius`` about the wall-frame point ``centre``."""
        return sum(seam.width * seam.length_within(centre, radius) for seam in self.seams)


def _sequence(values: Any, name: str) -> list[Any]:
    if values is None:
        return []
    if not isinstance(values, list):
        raise ParameterError(f'{name} must be a list, got {values!r}')
    return values


def _point(values: Any, name: str) -> tuple[float, float]:
    if not isinstance(values, (list, tuple)) or len(values) != 2:
        raise ParameterError(f'{name} must be a pair [X, Y], got {values!r}')
    return FINITE.check(name, values[0]), FINITE.check(name, values[1])


def _interval(values: Any, name: str) -> tuple[float, float]:
    low, high = _point(values, name)
    if not low < high:
        raise ParameterError(f'{name} must be [low, high] with low < high, got {list(values)}')
    return low, high
