"""The wall-climbing robot model of docs/model.md: pure NumPy, no ROS, no I/O.

The names below are loaded from their modules when first used: a process that needs the constraint set's names
(the trajectory and constraint_config nodes, the CLI's argument parsing) does not pay for the solver's SciPy.
"""

from __future__ import annotations

import importlib

EXPORTS = {
    'constraint_set': ('SELECTION_SYNTAX', 'STRUCTURAL', 'ConstraintSelection', 'build_modules'),
    'constraints': ('BaumgarteGains',),
    'errors': ('DivergedError', 'ModelError', 'ParameterError'),
    'outputs': ('DriveForces', 'StepOutputs', 'drive_forces'),
    'parameters': ('RobotParameters',),
    'robot': ('DOF', 'Adsorption', 'Robot', 'adsorption_analysis'),
    'scenario': ('Scenario', 'make_reference'),
    'simulation': ('DEFAULT_STEP', 'TIME_STEP', 'Simulation', 'SwitchReport'),
    'solver': ('ConstrainedMotion', 'solve', 'solve_with_factor'),
    'trajectories': ('Circle', 'FigureEight', 'Reference', 'ReferenceSample', 'SampledReference', 'SmoothStop',
                     'tangent_heading'),
}
"""The package's names, by the module that defines them."""
_MODULE_OF = {name: module for module, names in EXPORTS.items() for name in names}

__all__ = sorted(_MODULE_OF)


def __getattr__(name: str) -> object:
    module = _MODULE_OF.get(name)
    if module is None:
        raise AttributeError(f'module {__name__!r} has no attribute {name!r}')
    value = getattr(importlib.import_module(f'{__name__}.{module}'), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *__all__})
