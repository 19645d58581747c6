"""Controllers built on the model (pure NumPy, no ROS): what a user's controller node wraps."""

from wallbot_sim.control.tracking import ControllerGains, MotorCommand, TrackingController

__all__ = ['ControllerGains', 'MotorCommand', 'TrackingController']
