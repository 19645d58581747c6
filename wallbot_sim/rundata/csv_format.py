"""The CSV of a run (``wallbot-sim simulate --csv``): one row per step.

COLUMN_GROUPS is the one description of the columns: each group's names and how its values come
from a step's outputs, in order. Velocities are in the wall frame; ``err`` is the distance of the
centre from the reference point; ``Fx, Fy, Mz`` the constraint wrench Q_c on the chassis, ``tau1..tau4``
the total torque on each wheel (constraint torque, kinetic friction and its share of the motor torque:
``StepOutputs.wheel_torques``, what ``wheel_states`` carries as effort); ``F_left, F_right, F_lateral``
the drive forces (docs/model.md section 8); then the contact per wheel (docs/model.md
section 11.2): ``N1..N4`` the normal loads, ``use1..use4`` the friction use |f_i| / (mu_s N_i),
``slip1..slip4`` the slip flags (1 while the wheel slides), ``fx1..fx4`` and ``fy1..fy4`` the wall's
tangential force on the robot at each wheel along the body axes x_p and y_p (N).

A robot file's optional blocks (docs/model.md 13) append their columns (BLOCK_GROUPS), in that order:
``motor``: ``tau_L_applied, tau_R_applied``, the side torques acting (the command clipped to the
torque-speed envelope), then ``tau_L_cmd, tau_R_cmd``, the side torques commanded; ``adhesion``: ``dp, F_ad``, the vacuum chamber's pressure difference (Pa) and
adhesion force (N). A robot file without them writes CSV_COLUMNS alone.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Callable, Sequence

import numpy as np

from wallbot_sim.model import RobotParameters, StepOutputs
from wallbot_sim.model.outputs import StepTable

if TYPE_CHECKING:  # the batch package loads numba, which the CSV does not need
    from wallbot_sim.model.batch import BatchOutputs
    from wallbot_sim.model.batch.outputs import BatchTable


def _reference(out: StepOutputs) -> Sequence[float]:
    return out.reference.position if out.reference is not None else (math.nan, math.nan)


# arrays as lists: Python floats, not NumPy scalars one at a time (simulate writes a row every step)
COLUMN_GROUPS: tuple[tuple[tuple[str, ...], Callable[[StepOutputs], Sequence[float]]], ...] = (
    (('t',), lambda out: (out.t,)),
    (('x', 'y', 'theta', 'phi1', 'phi2', 'phi3', 'phi4'), lambda out: out.q.tolist()),
    (('vx', 'vy', 'omega', 'dphi1', 'dphi2', 'dphi3', 'dphi4'), lambda out: out.qd.tolist()),
    (('ref_x', 'ref_y'), _reference),
    (('err',), lambda out: (out.tracking_error,)),
    (('Fx', 'Fy', 'Mz'), lambda out: out.chassis_wrench.tolist()),
    (('tau1', 'tau2', 'tau3', 'tau4'), lambda out: out.wheel_torques.tolist()),
    (('F_left', 'F_right', 'F_lateral'), lambda out: (out.drive.left, out.drive.right, out.drive.lateral)),
    (('residual',), lambda out: (out.residual,)),
    (('N1', 'N2', 'N3', 'N4'), lambda out: out.contact.loads.tolist()),
    (('use1', 'use2', 'use3', 'use4'), lambda out: out.contact.wheel_use.tolist()),
    (('slip1', 'slip2', 'slip3', 'slip4'), lambda out: [int(flag) for flag in out.contact.wheel_slipping]),
    (('fx1', 'fx2', 'fx3', 'fx4'), lambda out: out.contact.wheel_forces[:, 0].tolist()),
    (('fy1', 'fy2', 'fy3', 'fy4'), lambda out: out.contact.wheel_forces[:, 1].tolist()),
)

CSV_COLUMNS = tuple(name for names, _values in COLUMN_GROUPS for name in names)
"""The header, in order."""


def csv_row(out: StepOutputs) -> list[float]:
    """One CSV row in the order of CSV_COLUMNS (flags as the integers 0 and 1)."""
    return [value if isinstance(value, int) else float(value) for _names, values in COLUMN_GROUPS for value in values(out)]


CSV_LINE_END = '\r\n'
"""``csv.writer``'s default line terminator."""
ColumnGroup = tuple[tuple[str, ...], Callable[[StepOutputs], Sequence[float]]]
BLOCK_GROUPS: dict[str, ColumnGroup] = {
    'motor': (('tau_L_applied', 'tau_R_applied', 'tau_L_cmd', 'tau_R_cmd'),
              lambda out: (*out.motor_torque, *out.motor_command)),
    'adhesion': (('dp', 'F_ad'), lambda out: out.vacuum),
}
"""The columns of each optional block of the robot file, appended in this order where the block is given."""


def block_groups(params: RobotParameters) -> tuple[ColumnGroup, ...]:
    """The column groups the blocks ``params`` has append."""
    return tuple(group for block, group in BLOCK_GROUPS.items() if getattr(params, block) is not None)


def block_columns(groups: Sequence[ColumnGroup]) -> tuple[str, ...]:
    """The names of ``groups``' columns, in order."""
    return tuple(name for names, _values in groups for name in names)


def csv_line(out: StepOutputs, groups: Sequence[ColumnGroup] = ()) -> str:
    """``csv_row`` (then the values of the blocks' ``groups``) as the line ``csv.writer`` writes for it,
    terminator included (faster than the writer).

    The writer quotes nothing here (a number's repr holds no comma, quote or line break) and writes
    each value as its repr; joining the reprs skips its per-field checks.
    """
    extra = [float(value) for _names, values in groups for value in values(out)]
    return ','.join(map(repr, csv_row(out) + extra)) + CSV_LINE_END


COLUMN = {name: i for i, name in enumerate(CSV_COLUMNS)}
"""Each column's index."""
_FLAGS = slice(COLUMN['slip1'], COLUMN['slip4'] + 1)


def fill_rows(out: StepTable, rows: np.ndarray, motor_torque: tuple[float, float]) -> None:
    """The CSV row (``csv_row``) of every instant of a table (constant ``motor_torque``, ideal contact) into
    ``rows`` (rows, len(CSV_COLUMNS))."""
    fill_motion_rows(out, rows, out.wheel_torques(motor_torque))
    fill_wheel_rows(rows, out.wheel_use, out.wheel_slipping, out.wheel_forces)


def fill_motion_rows(out: StepTable | BatchOutputs | BatchTable, rows: np.ndarray, wheel_torques: np.ndarray) -> None:
    """The columns t .. N4 of ``fill_rows`` (all but the wheels' use, slip and force), of a table, of the robots
    of a batch at one instant or of a batch's table ((robots, instants, columns) rows), with each wheel's total
    torque ``wheel_torques`` (rows' shape, 4)."""
    position = out.reference_position
    rows[..., COLUMN['t']] = out.t
    rows[..., COLUMN['x']:COLUMN['x'] + 7] = out.q
    rows[..., COLUMN['vx']:COLUMN['vx'] + 7] = out.qd
    rows[..., COLUMN['ref_x']:COLUMN['ref_y'] + 1] = position if position is not None else math.nan
    rows[..., COLUMN['err']] = out.tracking_error
    rows[..., COLUMN['Fx']:COLUMN['Fx'] + 3] = out.constraint_force[..., :3]
    rows[..., COLUMN['tau1']:COLUMN['tau1'] + 4] = wheel_torques
    rows[..., COLUMN['F_left']:COLUMN['F_left'] + 3] = out.drive
    rows[..., COLUMN['residual']] = out.residual
    rows[..., COLUMN['N1']:COLUMN['N1'] + 4] = out.loads


def fill_wheel_rows(rows: np.ndarray, use: np.ndarray, slipping: np.ndarray, forces: np.ndarray) -> None:
    """The wheels' columns of ``fill_rows``: use (rows' shape, 4), slip flags (rows' shape, 4), forces (rows' shape,
    4, 2)."""
    rows[..., COLUMN['use1']:COLUMN['use1'] + 4] = use
    rows[..., _FLAGS] = slipping
    rows[..., COLUMN['fx1']:COLUMN['fx1'] + 4] = forces[..., 0]
    rows[..., COLUMN['fy1']:COLUMN['fy1'] + 4] = forces[..., 1]


def csv_lines(rows: np.ndarray) -> str:
    """The lines ``csv_line`` writes for rows filled by ``fill_rows`` (the flags as the integers 0 and 1)."""
    lines = []
    for row, flags in zip(rows.tolist(), rows[:, _FLAGS].astype(int).tolist()):
        row[_FLAGS] = flags
        lines.append(','.join(map(repr, row)))
    lines.append('')
    return CSV_LINE_END.join(lines)
