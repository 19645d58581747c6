"""A run's time series, as one set of arrays whatever it was read from (a bag or a ``simulate`` CSV)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

MACHINE_SERIES = {'tau_L_applied': 'N m', 'tau_R_applied': 'N m', 'tau_L_cmd': 'N m', 'tau_R_cmd': 'N m', 'dp': 'Pa',
                  'F_ad': 'N'}
"""The machine's series a run may have (docs/model.md 13), with their units."""


@dataclass
class RunData:
    """Time series of one run (SI units, wall frame)."""

    label: str
    t: np.ndarray
    x: np.ndarray
    y: np.ndarray
    theta: np.ndarray
    vx: np.ndarray
    vy: np.ndarray
    omega: np.ndarray
    phi: np.ndarray
    """(N, 4) wheel spin angles, order of topics.WHEEL_JOINTS."""
    dphi: np.ndarray
    tau: np.ndarray
    ref_x: np.ndarray
    ref_y: np.ndarray
    err: np.ndarray
    Fx: np.ndarray
    Fy: np.ndarray
    Mz: np.ndarray
    F_left: np.ndarray
    F_right: np.ndarray
    F_lateral: np.ndarray
    residual: np.ndarray
    residual_settled: np.ndarray
    """The residual of the states at or after ``topics.RESIDUAL_SETTLED_AFTER`` (NaN elsewhere; from a bag, the
    largest of each diagnostics window, as ``residual``)."""
    path_x: np.ndarray = field(default_factory=lambda: np.empty(0))
    path_y: np.ndarray = field(default_factory=lambda: np.empty(0))
    """The full reference path if recorded (reference_path), else empty."""
    restarts: int = 0
    """How often odometry time jumped back in the bag (earlier runs are not in these arrays)."""
    loads: np.ndarray = field(default_factory=lambda: np.empty((0, 4)))
    """(N, 4) normal load of each wheel (N); NaN where not recorded."""
    use: np.ndarray = field(default_factory=lambda: np.empty((0, 4)))
    """(N, 4) friction use of each wheel, |f_i| / (mu_s N_i)."""
    slip: np.ndarray = field(default_factory=lambda: np.empty((0, 4)))
    """(N, 4) 1 where a wheel slides, 0 where it sticks."""
    wheel_forces: np.ndarray = field(default_factory=lambda: np.empty((0, 4, 2)))
    """(N, 4, 2) the wall's tangential force on the robot at each wheel, body axes x_p, y_p (N)."""
    sensed: np.ndarray = field(default_factory=lambda: np.empty((0, 6)))
    """(N, 6) x, y, theta, vx, vy, omega as the noisy odometry reported them (a run with sensor
    noise; NaN where a stamp has none), empty when the odometry was the simulated state itself."""
    machine: dict[str, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict)
    """The machine's series the run has (MACHINE_SERIES' names), each (times (s), values): a CSV's block columns
    (``tau_L_applied, tau_R_applied, tau_L_cmd, tau_R_cmd``, ``dp, F_ad``); a bag's side torques applied and
    commanded where its robot file has a motor block, and ``dp`` from its chamber_pressure."""

    def __len__(self) -> int:
        return len(self.t)
