"""N robots advanced at once: the model of wallbot_sim.model vectorized over a batch (pure NumPy).

Every robot has its own parameters and state; all share the scenario's reference, the constraint
selection, the time step and the clock. Robot by robot the batch agrees with ``Simulation``.
"""

from wallbot_sim.model.batch.control import BatchTrackingController
from wallbot_sim.model.batch.constraints import BATCH_MODULES, BatchGains, build_batch_modules
from wallbot_sim.model.batch.robots import RobotBatch
from wallbot_sim.model.batch.simulation import BatchOutputs, BatchSimulation
from wallbot_sim.model.batch.solver import batch_constrained_acceleration, minimum_norm_least_squares

__all__ = [
    'BATCH_MODULES', 'BatchGains', 'BatchOutputs', 'BatchSimulation', 'BatchTrackingController', 'RobotBatch',
    'batch_constrained_acceleration', 'build_batch_modules', 'minimum_norm_least_squares',
]
