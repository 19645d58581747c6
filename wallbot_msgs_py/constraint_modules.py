"""The constraint modules a graph can switch: the one table of their names, order and switches.

Everything that lists the modules follows it: the simulator's constraint set (``wallbot_sim.model.constraint_set``:
its modules, ``ConstraintSelection``'s fields, the batch's modules and the compiled kernel's flags and rows),
constraint_config's parameters, the ``constraints`` message and the dynamics' state snapshot. It imports nothing,
so the model may read it (the one module of this package the model imports; setup.cfg says so).
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class ConstraintSwitch:
    """The constraint_config parameter that switches one constraint module, under the same name in the
    ``constraints`` message and in the dynamics' state snapshot, and what the module is."""

    parameter: str
    default: bool
    description: str
    task: bool = False
    """A task on the reference trajectory (stacked before the structural and environmental constraints)."""


CONSTRAINT_MODULES = {
    'trajectory': ConstraintSwitch('trajectory_task', True, 'the centre follows the reference trajectory '
                                                            '(off = driven by wheel_torque_cmd)', task=True),
    'belt': ConstraintSwitch('belt', False, 'synchronous toothed belt: front and rear wheel of a side turn together'),
    'non_lateral': ConstraintSwitch('non_lateral', False, 'the centre does not move sideways'),
    'nonslip': ConstraintSwitch('nonslip', False, 'each wheel rolls on the wall without longitudinal slip'),
    'tangent_heading': ConstraintSwitch('tangent_heading', True,
                                        'heading task along the path whenever non_lateral is on with the trajectory '
                                        "task (false gives the paper's inconsistent set)", task=True),
}
"""Every constraint module, keyed by its name (the simulator's, also in the ``constraints`` message's 'active'
list and its label), in the order of their switches: in the messages, in the snapshot and of
``ConstraintSelection``'s fields."""
CONSTRAINT_SWITCHES = tuple(switch.parameter for switch in CONSTRAINT_MODULES.values())
"""The switches' parameter names, in the table's order."""
TASKS = tuple(name for name, switch in CONSTRAINT_MODULES.items() if switch.task)
"""The tasks on the reference, in the table's order."""
STRUCTURAL = tuple(name for name, switch in CONSTRAINT_MODULES.items() if not switch.task)
"""The structural and environmental constraints, in the paper's order (the table's)."""
STACKING_ORDER = TASKS + STRUCTURAL
"""The order in which the active modules' rows are stacked into A and b (and named in a label): the tasks first."""
