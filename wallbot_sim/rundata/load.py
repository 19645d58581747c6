"""One loader for a run: a recorded bag (``bag_run``) or a ``simulate`` CSV, as the same arrays (``RunData``).

From a CSV the residual after the start is the residual of the rows at or after ``topics.RESIDUAL_SETTLED_AFTER``;
a robot file's blocks append their columns (``MACHINE_SERIES``).
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np

from wallbot_msgs_py import topics
from wallbot_sim.rundata.csv_format import BLOCK_GROUPS, CSV_COLUMNS, block_columns
from wallbot_sim.rundata.bag_run import load_bag_run
from wallbot_sim.rundata.errors import RunDataError
from wallbot_sim.rundata.run_data import MACHINE_SERIES, RunData

BLOCK_COLUMNS = set(block_columns(tuple(BLOCK_GROUPS.values())))
"""The columns a robot file's blocks append (RunData.machine)."""


RUN_BAG = 'bag'
"""The bag's name in a run's folder (``wallbot-sim run --out DIR`` records DIR/bag)."""


def run_label(path: Path | str) -> str:
    """What names a run in figures and reports: a CSV's (or a lone .mcap's) stem; a bag's folder, or for a
    run's own bag (DIR/bag, or DIR/bag/bag.mcap) the run's folder DIR."""
    path = Path(path).resolve()
    suffix = path.suffix.lower()
    if suffix == '.csv' or (suffix == '.mcap' and not (path.parent / 'metadata.yaml').is_file()):
        return path.stem
    bag = path.parent if suffix == '.mcap' else path
    return bag.parent.name if bag.name == RUN_BAG and bag.parent.name else bag.name


BAG_FILES = ('.mcap', '.db3', 'metadata.yaml')
"""How the files inside a bag directory that name it end."""


def is_csv(path: Path) -> bool:
    """Whether the existing ``path`` is a run's CSV (else a bag); RunDataError naming both kinds if it is neither
    (the verbs reading a run take either)."""
    if not path.exists():
        raise RunDataError(f'{path} does not exist')
    if path.is_dir() or path.name.endswith(BAG_FILES):
        return False
    if path.suffix.lower() == '.csv':
        return True
    raise RunDataError(f'{path} is neither a simulate CSV (.csv) nor a rosbag2 bag (a bag directory, or its .mcap)')


def load_run(path: Path | str, label: str | None = None) -> RunData:
    """A bag directory (or its .mcap) or a simulate CSV; RunDataError / BagError otherwise. Labelled
    ``label`` or by ``run_label``."""
    path = Path(path)
    label = label or run_label(path)
    if is_csv(path):
        return _load_csv(path, label)
    return load_bag_run(path, label)


def _load_csv(path: Path, label: str) -> RunData:
    try:
        with open(path, newline='', encoding='utf-8') as stream:
            reader = csv.reader(stream)
            header = next(reader, None)
            if header is None or tuple(header[:len(CSV_COLUMNS)]) != CSV_COLUMNS or not set(
                    header[len(CSV_COLUMNS):]) <= BLOCK_COLUMNS:
                raise RunDataError(f'{path} is not a wallbot-sim simulate CSV (header differs)')
            rows = np.array([[float(v) for v in row] for row in reader if row], dtype=float)
    except OSError as error:
        raise RunDataError(f'cannot read {path}: {error.strerror}') from None
    except ValueError:
        raise RunDataError(f'{path} has a non-numeric value') from None
    if rows.size == 0:
        raise RunDataError(f'{path} has no data rows')
    run = run_from_columns(rows[:, :len(CSV_COLUMNS)], label)
    run.machine = {name: (run.t, rows[:, i]) for i, name in enumerate(header) if name in MACHINE_SERIES}
    return run


def run_from_columns(rows: np.ndarray, label: str) -> RunData:
    """The run whose steps are ``rows`` (steps, len(CSV_COLUMNS)), in the order of CSV_COLUMNS: a simulate
    CSV's numbers, read or still in memory."""
    col = {name: rows[:, i] for name, i in _COLUMN_INDEX.items()}

    def wheels(prefix: str) -> np.ndarray:
        return rows[:, _WHEEL_COLUMNS[prefix]]
    return RunData(label, col['t'], col['x'], col['y'], col['theta'], col['vx'], col['vy'], col['omega'],
                   wheels('phi'), wheels('dphi'), wheels('tau'),
                   col['ref_x'], col['ref_y'], col['err'], col['Fx'], col['Fy'], col['Mz'],
                   col['F_left'], col['F_right'], col['F_lateral'], col['residual'],
                   np.where(col['t'] >= topics.RESIDUAL_SETTLED_AFTER - 1e-9, col['residual'], math.nan),
                   loads=wheels('N'), use=wheels('use'), slip=wheels('slip'),
                   wheel_forces=rows[:, _FORCE_COLUMNS].reshape(len(rows), 4, 2))


_COLUMN_INDEX = {name: i for i, name in enumerate(CSV_COLUMNS)}
"""Each column's place in a row."""
_WHEEL_COLUMNS = {prefix: [_COLUMN_INDEX[f'{prefix}{i}'] for i in range(1, 5)]
                  for prefix in ('phi', 'dphi', 'tau', 'N', 'use', 'slip')}
"""Each per-wheel series' columns, wheels 1 to 4."""
_FORCE_COLUMNS = [_COLUMN_INDEX[f'{axis}{i}'] for i in range(1, 5) for axis in ('fx', 'fy')]
"""The wheel forces' columns, wheel by wheel, x_p then y_p."""
