"""The CSV of a run (``wallbot-sim simulate --csv``): one row per step, the one list of its columns.

Velocities are in the wall frame; ``err`` is the distance of the centre from the reference
point; ``Fx..tau4`` are the constraint force Q_c; ``F_left, F_right, F_lateral`` the drive forces
(docs/model.md section 8).
"""

from __future__ import annotations

import math

from wallbot_sim.model import StepOutputs

CSV_COLUMNS = (
    't', 'x', 'y', 'theta', 'phi1', 'phi2', 'phi3', 'phi4', 'vx', 'vy', 'omega',
    'dphi1', 'dphi2', 'dphi3', 'dphi4', 'ref_x', 'ref_y', 'err', 'Fx', 'Fy', 'Mz',
    'tau1', 'tau2', 'tau3', 'tau4', 'F_left', 'F_right', 'F_lateral', 'residual')


def csv_row(out: StepOutputs) -> list[float]:
    """One CSV row in the order of CSV_COLUMNS."""
    ref = out.reference.position if out.reference is not None else (math.nan, math.nan)
    return [out.t, *out.q, *out.qd, *ref, out.tracking_error, *out.constraint_force,
            out.drive.left, out.drive.right, out.drive.lateral, out.residual]
