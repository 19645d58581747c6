"""Which constraint modules are active, and building them for a robot and a reference."""

from __future__ import annotations

from dataclasses import dataclass

from wallbot_sim.model.constraints import (
    BaumgarteGains, ConstraintModule, NonLateral, Nonslip, SynchronousBelt, TangentHeadingTask,
    TrajectoryTask)
from wallbot_sim.model.errors import ParameterError
from wallbot_sim.model.robot import Robot
from wallbot_sim.model.trajectories import Reference

STRUCTURAL = ('belt', 'non_lateral', 'nonslip')
"""Names of the structural and environmental constraints, in the paper's order."""


@dataclass(frozen=True)
class ConstraintSelection:
    """The module switches of docs/model.md section 5.

    ``tangent_heading`` None means the default: on whenever non-lateral motion is constrained
    together with the trajectory task (without it that set is inconsistent).
    """

    trajectory: bool = True
    belt: bool = False
    non_lateral: bool = False
    nonslip: bool = False
    tangent_heading: bool | None = None

    @classmethod
    def parse(cls, text: str, trajectory: bool = True, tangent_heading: bool | None = None) -> ConstraintSelection:
        """From a comma list of belt, non_lateral, nonslip, or 'none' (the trajectory task only)."""
        names = [name.strip() for name in text.split(',') if name.strip()]
        if names == ['none']:
            names = []
        unknown = [name for name in names if name not in STRUCTURAL]
        if unknown or not text.strip():
            bad = unknown[0] if unknown else text
            raise ParameterError(f'unknown constraint {bad!r}: use a comma list of {", ".join(STRUCTURAL)}, or none')
        return cls(trajectory, *(name in names for name in STRUCTURAL), tangent_heading)

    @property
    def heading(self) -> bool:
        """Whether the tangent-heading task is active."""
        if not self.trajectory:
            return False
        return self.non_lateral if self.tangent_heading is None else self.tangent_heading

    def active_names(self) -> list[str]:
        """Names of the active modules, in stacking order."""
        flags = {'trajectory': self.trajectory, 'tangent_heading': self.heading, 'belt': self.belt,
                 'non_lateral': self.non_lateral, 'nonslip': self.nonslip}
        return [name for name, on in flags.items() if on]

    def label(self) -> str:
        """Short human-readable name, e.g. 'trajectory+tangent_heading+belt'."""
        return '+'.join(self.active_names()) or 'free'


MODULES = ('trajectory', 'tangent_heading', 'belt', 'non_lateral', 'nonslip')
"""Every module a selection can switch on, in stacking order."""


def make_module(name: str, robot: Robot, reference: Reference | None, gains: BaumgarteGains) -> ConstraintModule:
    """The constraint module called ``name`` (one of MODULES) for ``robot``."""
    if name in ('trajectory', 'tangent_heading') and reference is None:
        raise ParameterError(f'the {name} task needs a reference')
    if name == 'trajectory':
        return TrajectoryTask(reference, gains)
    if name == 'tangent_heading':
        return TangentHeadingTask(reference, gains)
    if name == 'belt':
        return SynchronousBelt(gains)
    if name == 'non_lateral':
        return NonLateral(gains)
    if name == 'nonslip':
        return Nonslip(robot.params.wheel_radius, robot.lateral_offsets, gains)
    raise ParameterError(f'unknown constraint module {name!r} (known: {", ".join(MODULES)})')


def build_modules(selection: ConstraintSelection, robot: Robot, reference: Reference | None,
                  gains: BaumgarteGains) -> list[ConstraintModule]:
    """The active constraint modules, in the order of ``selection.active_names()``."""
    return [make_module(name, robot, reference, gains) for name in selection.active_names()]
