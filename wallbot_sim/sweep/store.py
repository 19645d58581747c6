"""A sweep's output directory: what it holds and how a rerun resumes.

    DIR/sweep.json          which sweep this is (a fingerprint of the spec's robots and runs)
    DIR/chunks/NNNNNN.csv   the results of one finished chunk (written whole, or not at all)
    DIR/results.csv         every robot's row, once all chunks are done
    DIR/*.png               the figures

A rerun with the same spec finds the finished chunks and computes only the others; a different spec
is refused rather than mixed in.
"""

from __future__ import annotations

import csv
import hashlib
import io
import json
import math
import os
from pathlib import Path
from typing import Any, Sequence

from wallbot_sim.sweep.compute import OUTPUTS
from wallbot_sim.sweep.errors import SweepError
from wallbot_sim.sweep.spec import SweepSpec

RESULTS = 'results.csv'
PAIR_KEYS = {'com_offset': ('com_offset_x', 'com_offset_y')}
"""Robot-file keys whose value is a pair: one column per element."""


def parameter_columns(spec: SweepSpec) -> list[str]:
    """The results columns of the varied parameters, in the spec's order."""
    return [column for key in spec.varied for column in PAIR_KEYS.get(key, (key,))]


def header(spec: SweepSpec) -> list[str]:
    """The results header: robot index, varied parameters, outputs."""
    return ['robot', *parameter_columns(spec), *OUTPUTS]


def fingerprint(spec: SweepSpec) -> str:
    """What makes two sweeps the same: every robot's parameters, the runs, the chunking."""
    text = repr((spec.settings, spec.base, spec.robots, spec.chunk_size))
    return hashlib.sha256(text.encode()).hexdigest()


class SweepDirectory:
    """The output directory of one sweep."""

    def __init__(self, path: Path | str, spec: SweepSpec) -> None:
        self.path, self.spec = Path(path), spec
        self.chunk_dir = self.path / 'chunks'
        self.results = self.path / RESULTS

    def open(self) -> bool:
        """Create the directory, or check that it holds this sweep; SweepError if another. Whether it was created."""
        identity = {'fingerprint': fingerprint(self.spec), 'robots': len(self.spec.robots),
                    'chunk_size': self.spec.chunk_size, 'varied': list(self.spec.varied)}
        marker = self.path / 'sweep.json'
        try:
            if marker.exists():
                held = json.loads(marker.read_text(encoding='utf-8'))
                if held.get('fingerprint') != identity['fingerprint']:
                    raise SweepError(f'{self.path} holds another sweep (its spec differs): give another --out, '
                                     'or remove it')
                return False
            if self.path.exists() and any(self.path.iterdir()):
                raise SweepError(f'{self.path} is not empty and holds no sweep: give another --out')
            created = not self.path.exists()
            self.chunk_dir.mkdir(parents=True, exist_ok=True)
            _write_atomically(marker, json.dumps(identity, indent=2) + '\n')
            return created
        except OSError as error:
            raise SweepError(f'cannot use {self.path}: {error.strerror}') from None
        except ValueError:
            raise SweepError(f'{marker} is not a sweep marker (not JSON): give another --out') from None

    def remove_unused(self) -> None:
        """Remove the directory :meth:`open` created if no chunk was written into it (a sweep that could not
        start leaves nothing behind)."""
        if any(self.chunk_dir.iterdir()):
            return
        self.chunk_dir.rmdir()
        (self.path / 'sweep.json').unlink()
        self.path.rmdir()

    def chunk_path(self, index: int) -> Path:
        return self.chunk_dir / f'{index:06d}.csv'

    def pending(self) -> list[int]:
        """The chunks without a results file, in order."""
        return [index for index in range(len(self.spec.chunks())) if not self.chunk_path(index).exists()]

    def write_chunk(self, index: int, outputs: Sequence[Sequence[float]]) -> None:
        """Store chunk ``index``'s rows (its robots' OUTPUTS, in order), all at once."""
        robots = self.spec.chunks()[index]
        if len(outputs) != len(robots):
            raise SweepError(f'chunk {index} returned {len(outputs)} rows for {len(robots)} robots')
        text = io.StringIO()
        writer = csv.writer(text, lineterminator='\n')
        for robot, row in zip(robots, outputs):
            writer.writerow([robot, *self._parameters(robot), *(_text(value) for value in row)])
        try:
            _write_atomically(self.chunk_path(index), text.getvalue())
        except OSError as error:
            raise SweepError(f'cannot write {self.chunk_path(index)}: {error.strerror}') from None

    def assemble(self) -> Path:
        """Write results.csv from every chunk (all must be done)."""
        missing = self.pending()
        if missing:
            raise SweepError(f'{len(missing)} chunk(s) of {self.path} are not done')
        body = ''.join(self.chunk_path(index).read_text(encoding='utf-8') for index in range(len(self.spec.chunks())))
        _write_atomically(self.results, ','.join(header(self.spec)) + '\n' + body)
        return self.results

    def _parameters(self, robot: int) -> list[str]:
        values = self.spec.robots[robot]
        texts = []
        for key in self.spec.varied:
            value = values[key]
            texts.extend(_text(v) for v in (value if key in PAIR_KEYS else (value,)))
        return texts


def read_results(path: Path | str) -> tuple[list[str], list[list[float]]]:
    """Header and rows of a results.csv (numbers as floats)."""
    with open(path, newline='', encoding='utf-8') as stream:
        reader = csv.reader(stream)
        names = next(reader)
        return names, [[float(value) if value else math.nan for value in row] for row in reader]


def _text(value: Any) -> str:
    """A number as CSV text that reads back exactly (None: empty)."""
    if value is None:
        return ''
    if isinstance(value, (bool, int)):
        return str(int(value))
    return repr(float(value))


def _write_atomically(path: Path, text: str) -> None:
    temporary = path.with_name(path.name + '.part')
    temporary.write_text(text, encoding='utf-8')
    os.replace(temporary, path)
