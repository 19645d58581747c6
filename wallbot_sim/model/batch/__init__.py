"""N robots advanced at once: the model of wallbot_sim.model vectorized over a batch (pure NumPy; numba optional).

Every robot has its own parameters (any ``RobotParameters``: masses, CoM, inertias, adhesion force,
friction, Baumgarte gains), initial state and motor torques; all share the scenario's reference,
the constraint selection, the contact model, the time step and the clock. Robot by robot the batch
agrees with ``Simulation`` (and its closed loop with ``simulate --controller``'s).

Public entry points (stable; a sweep builds on these):

``BatchSimulation(robots, reference, selection, q0, qd0, dt=DEFAULT_STEP, t0=0.0, gains=None,
contact='ideal', engine='numpy')``, or ``BatchSimulation.from_scenario(robots, scenario, selection,
dt, contact, engine)`` with every robot at the scenario's start.
    ``robots``: a sequence of ``Robot``; ``q0``, ``qd0``: (N, 7). ``contact``: 'ideal' or 'coulomb'
    (coulomb applies without the trajectory task, as in ``Simulation``). ``engine``: 'numpy', or
    'numba' (the compiled ideal-contact step of ``kernel``; ``kernel.available()`` says whether
    numba is installed).

    ``set_motor_torque(torques)``: (N, 2) or one pair for all. ``step()``; ``run(steps, on_step=None)``:
    ``on_step(BatchOutputs)`` at every instant, both ends included, as ``Simulation.run``; it returns
    the final outputs (with no hook none are computed: the fastest way to advance). ``outputs()``:
    ``BatchOutputs`` now. ``t``, ``steps``, ``q``, ``qd``; with coulomb contact ``detached`` (N,) bool,
    ``t_detached`` (N,) s (NaN: on the wall), ``detached_wheel`` (N,) 1..4 (0: none), ``lift_off(i)`` the
    ``DetachedError`` ``Simulation.step`` raises for robot i alone (None: on the wall). A detached robot
    keeps its state; the others go on. DivergedError names robots whose state stops being finite.

``BatchOutputs``: t; q, qd, acceleration, constraint_force (N, 7); residual (N,); motor_torque
(N, 2); drive (N, 3) = (F_L, F_R, F_lat); loads (N, 4); use (N, 3); slipping (N, 3) bool;
friction_force (N, 7); detached (N,); reference; properties wheel_torques (N, 4), tracking_error (N,).

``BatchTrackingController(controller_robots, reference, gains, rate_hz, max_wheel_torque)``: the
example controller per robot (``controller_robots[i]``, e.g. ``control.sampling.controller_robot(
params_i, mass_scale_i)``); ``hook(simulation)`` is an ``on_step`` closing the loop at ``rate_hz``.
Several hooks: call them in order from one ``on_step``.

``BatchRecorder(fields, every=1)``: an ``on_step`` keeping per-robot time series of BatchOutputs fields.
"""

from wallbot_sim.model.batch.constraints import BATCH_MODULES, BatchGains, build_batch_modules
from wallbot_sim.model.batch.control import BatchTrackingController
from wallbot_sim.model.batch.outputs import BatchOutputs, BatchRecorder
from wallbot_sim.model.batch.robots import RobotBatch
from wallbot_sim.model.batch.simulation import ENGINES, BatchSimulation
from wallbot_sim.model.batch.solver import batch_constrained_acceleration, minimum_norm_least_squares

__all__ = [
    'BATCH_MODULES', 'ENGINES', 'BatchGains', 'BatchOutputs', 'BatchRecorder', 'BatchSimulation',
    'BatchTrackingController', 'RobotBatch', 'batch_constrained_acceleration', 'build_batch_modules',
    'minimum_norm_least_squares',
]
