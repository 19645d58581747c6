"""The CSV of a run (``wallbot-sim simulate --csv``): one row per step.

COLUMN_GROUPS is the one description of the columns: each group's names and how its values come
from a step's outputs, in order. Velocities are in the wall frame; ``err`` is the distance of the
centre from the reference point; ``Fx..tau4`` are the constraint force Q_c; ``F_left, F_right,
F_lateral`` the drive forces (docs/model.md section 8); ``N1..N4`` the normal loads, ``use_*`` the
friction use and ``slip_*`` the slip flags of the contact (docs/model.md section 11).
"""

from __future__ import annotations

import math
from typing import Callable, Sequence

from wallbot_sim.model import StepOutputs


def _reference(out: StepOutputs) -> Sequence[float]:
    return out.reference.position if out.reference is not None else (math.nan, math.nan)


# arrays as lists: Python floats, not NumPy scalars one at a time (simulate writes a row every step)
COLUMN_GROUPS: tuple[tuple[tuple[str, ...], Callable[[StepOutputs], Sequence[float]]], ...] = (
    (('t',), lambda out: (out.t,)),
    (('x', 'y', 'theta', 'phi1', 'phi2', 'phi3', 'phi4'), lambda out: out.q.tolist()),
    (('vx', 'vy', 'omega', 'dphi1', 'dphi2', 'dphi3', 'dphi4'), lambda out: out.qd.tolist()),
    (('ref_x', 'ref_y'), _reference),
    (('err',), lambda out: (out.tracking_error,)),
    (('Fx', 'Fy', 'Mz', 'tau1', 'tau2', 'tau3', 'tau4'), lambda out: out.constraint_force.tolist()),
    (('F_left', 'F_right', 'F_lateral'), lambda out: (out.drive.left, out.drive.right, out.drive.lateral)),
    (('residual',), lambda out: (out.residual,)),
    (('N1', 'N2', 'N3', 'N4'), lambda out: out.contact.loads.tolist()),
    (('use_L', 'use_R', 'use_lat'), lambda out: out.contact.use),
    (('slip_L', 'slip_R', 'slip_lat'), lambda out: [int(flag) for flag in out.contact.slipping]),
)

CSV_COLUMNS = tuple(name for names, _values in COLUMN_GROUPS for name in names)
"""The header, in order."""


def csv_row(out: StepOutputs) -> list[float]:
    """One CSV row in the order of CSV_COLUMNS (flags as the integers 0 and 1)."""
    return [value if isinstance(value, int) else float(value) for _names, values in COLUMN_GROUPS for value in values(out)]


CSV_LINE_END = '\r\n'
"""``csv.writer``'s default line terminator."""


def csv_line(out: StepOutputs) -> str:
    """``csv_row`` as the line ``csv.writer`` writes for it, terminator included (faster than the writer).

    The writer quotes nothing here (a number's repr holds no comma, quote or line break) and writes
    each value as its repr; joining the reprs skips its per-field checks.
    """
    return ','.join(map(repr, csv_row(out))) + CSV_LINE_END
