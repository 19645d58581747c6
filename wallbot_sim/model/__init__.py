"""The wall-climbing robot model of docs/model.md: pure NumPy, no ROS, no I/O."""

from wallbot_sim.model.constraint_set import SELECTION_SYNTAX, STRUCTURAL, ConstraintSelection, build_modules
from wallbot_sim.model.constraints import BaumgarteGains
from wallbot_sim.model.errors import ModelError, ParameterError
from wallbot_sim.model.outputs import DriveForces, StepOutputs, drive_forces
from wallbot_sim.model.parameters import RobotParameters
from wallbot_sim.model.robot import DOF, Adsorption, Robot, adsorption_analysis
from wallbot_sim.model.scenario import Scenario, make_reference
from wallbot_sim.model.simulation import DEFAULT_STEP, TIME_STEP, DivergedError, Simulation, SwitchReport
from wallbot_sim.model.solver import ConstrainedMotion, solve, solve_with_factor
from wallbot_sim.model.trajectories import (
    Circle, FigureEight, Reference, ReferenceSample, SampledReference, SmoothStop, tangent_heading)

__all__ = [
    'DEFAULT_STEP', 'DOF', 'SELECTION_SYNTAX', 'STRUCTURAL', 'Adsorption', 'BaumgarteGains', 'Circle',
    'ConstrainedMotion', 'ConstraintSelection', 'DivergedError', 'DriveForces', 'FigureEight',
    'ModelError', 'ParameterError', 'Reference', 'ReferenceSample', 'Robot', 'RobotParameters',
    'SampledReference', 'Scenario', 'Simulation', 'SmoothStop', 'StepOutputs', 'SwitchReport', 'TIME_STEP',
    'adsorption_analysis', 'build_modules', 'drive_forces', 'make_reference', 'solve',
    'solve_with_factor', 'tangent_heading',
]
