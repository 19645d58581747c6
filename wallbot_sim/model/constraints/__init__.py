"""Constraint modules: each contributes its rows A_k qdd = b_k; the solver stacks them."""

from wallbot_sim.model.constraints.base import (
    CHANNELS, LATERAL, LEFT, LONGITUDINAL, RIGHT, WHEEL_DIRECTIONS, BaumgarteGains, ConstraintModule, ContactConstraint,
    VelocityConstraint)
from wallbot_sim.model.constraints.belt import SynchronousBelt
from wallbot_sim.model.constraints.look_ahead import LookAheadPointTask
from wallbot_sim.model.constraints.non_lateral import NonLateral
from wallbot_sim.model.constraints.nonslip import Nonslip
from wallbot_sim.model.constraints.trajectory import TangentHeadingTask, TrajectoryTask, wrap_angle
from wallbot_sim.model.constraints.wheel_contact import WheelContact

__all__ = [
    'CHANNELS', 'LATERAL', 'LEFT', 'LONGITUDINAL', 'RIGHT', 'WHEEL_DIRECTIONS', 'BaumgarteGains', 'ConstraintModule',
    'ContactConstraint', 'LookAheadPointTask', 'NonLateral', 'Nonslip', 'SynchronousBelt',
    'TangentHeadingTask', 'TrajectoryTask', 'VelocityConstraint', 'WheelContact', 'wrap_angle',
]
