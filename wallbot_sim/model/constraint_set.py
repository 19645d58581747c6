"""Which constraint modules are active, and building them for a robot and a reference."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

from wallbot_msgs_py.constraint_modules import CONSTRAINT_MODULES, STACKING_ORDER, STRUCTURAL
from wallbot_sim.model.constraints import (
    BaumgarteGains, ConstraintModule, NonLateral, Nonslip, SynchronousBelt, TangentHeadingTask,
    TrajectoryTask)
from wallbot_sim.model.errors import ParameterError
from wallbot_sim.model.robot import Robot
from wallbot_sim.model.trajectories import Reference

Builder = Callable[[Robot, 'Reference | None', BaumgarteGains], ConstraintModule]


@dataclass(frozen=True)
class ModuleKind:
    """How to build one kind of constraint module, its row count, and whether it is a task on the reference."""

    build: Builder
    rows: int
    """k, the same at every state (the compiled kernel lays out the modules' rows by it)."""
    task: bool


_BUILDERS: dict[str, tuple[Builder, int]] = {
    'trajectory': (lambda robot, reference, gains: TrajectoryTask(reference, gains), 2),
    'tangent_heading': (lambda robot, reference, gains: TangentHeadingTask(reference, gains), 1),
    'belt': (lambda robot, reference, gains: SynchronousBelt(gains), 2),
    'non_lateral': (lambda robot, reference, gains: NonLateral(gains), 1),
    'nonslip': (lambda robot, reference, gains: Nonslip(robot.params.wheel_radius, robot.lateral_offsets, gains),
                4),  # one row per wheel
}
"""How to build each module of ``wallbot_msgs_py.constraint_modules``' table, and its row count."""
MODULES: dict[str, ModuleKind] = {name: ModuleKind(*_BUILDERS[name], task=CONSTRAINT_MODULES[name].task)
                                  for name in STACKING_ORDER}
"""Every constraint module a selection can switch on, keyed by name, in stacking order: the modules, names, order and
kinds of ``wallbot_msgs_py.constraint_modules.CONSTRAINT_MODULES`` (the names the command line, the nodes and the
``constraints`` message use, each with its constraint_config switch)."""
SELECTION_SYNTAX = f'comma list of {", ".join(STRUCTURAL)}, or none'
"""How a selection is written (:meth:`ConstraintSelection.parse`; ``--constraints``, ``constraints:=``)."""


@dataclass(frozen=True)
class ConstraintSelection:
    """The module switches of docs/model.md section 5: one field per module of ``MODULES``, in the order of the
    table's switches (``wallbot_msgs_py.constraint_modules.CONSTRAINT_MODULES``).

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
        """From a comma list of STRUCTURAL's names, or 'none' (the trajectory task only)."""
        names = [name.strip() for name in text.split(',') if name.strip()]
        if names == ['none']:
            names = []
        unknown = [name for name in names if name not in STRUCTURAL]
        if unknown or not text.strip():
            bad = unknown[0] if unknown else text
            raise ParameterError(f'unknown constraint {bad!r}: use a {SELECTION_SYNTAX}')
        return cls(trajectory=trajectory, tangent_heading=tangent_heading,
                   **{name: name in names for name in STRUCTURAL})

    @classmethod
    def structural(cls, trajectory: bool = True) -> ConstraintSelection:
        """Every structural constraint on (the driven robot's set without the trajectory task)."""
        return cls(trajectory=trajectory, **dict.fromkeys(STRUCTURAL, True))

    @property
    def heading(self) -> bool:
        """Whether the tangent-heading task is active."""
        if not self.trajectory:
            return False
        return self.non_lateral if self.tangent_heading is None else self.tangent_heading

    def active_names(self) -> list[str]:
        """Names of the active modules, in stacking order."""
        return [name for name in MODULES if (self.heading if name == 'tangent_heading' else getattr(self, name))]

    def label(self) -> str:
        """Short human-readable name, e.g. 'trajectory+tangent_heading+belt'."""
        return '+'.join(self.active_names()) or 'free'


def make_module(name: str, robot: Robot, reference: Reference | None, gains: BaumgarteGains) -> ConstraintModule:
    """The constraint module called ``name`` (one of MODULES) for ``robot``."""
    kind = MODULES.get(name)
    if kind is None:
        raise ParameterError(f'unknown constraint module {name!r} (known: {", ".join(MODULES)})')
    if kind.task and reference is None:
        raise ParameterError(f'the {name} task needs a reference')
    return kind.build(robot, reference, gains)


def build_modules(selection: ConstraintSelection, robot: Robot, reference: Reference | None,
                  gains: BaumgarteGains) -> list[ConstraintModule]:
    """The active constraint modules, in the order of ``selection.active_names()``."""
    return [make_module(name, robot, reference, gains) for name in selection.active_names()]
