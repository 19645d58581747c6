"""What the documents quote beside their commands, checked against what those commands print and write.

Each ``Claim`` finds its numbers in the document's text (whitespace folded) with a pattern, one group a
number, and measures them from the page's runs (``Ran``): a command's output or a file it wrote. A number
holds within one unit of its last quoted digit (``doc_blocks.agrees``), or the relative tolerance the claim
states; a bound ("below 1e-9 m") holds when the measured value is below it. A document rewritten so that a
pattern no longer finds its number fails ``test_docs.py`` at once, so a claim cannot go stale unnoticed.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Sequence

import numpy as np
import pytest

from doc_blocks import REPO_ROOT, BlockRun, agrees, blocks, missing_output, run_document


@dataclass
class Ran:
    """A page's bash blocks, run in order in ``folder``."""

    folder: Path
    runs: list[BlockRun]
    tables: dict[str, np.ndarray] = field(default_factory=dict)

    def printed(self, command: str) -> str:
        """What the one command containing ``command`` printed."""
        matching = [run for run in self.runs if any(command in written for written in run.commands)]
        if len(matching) != 1:
            raise KeyError(f'{len(matching)} blocks run a command containing {command!r}')
        return matching[0].printed_by(command)

    def number(self, command: str, pattern: str) -> float:
        """The number ``pattern``'s group finds in what ``command`` printed."""
        match = re.search(pattern, self.printed(command))
        if match is None:
            raise AssertionError(f'{command!r} printed no {pattern!r}')
        return float(match.group(1))

    def csv(self, name: str) -> np.ndarray:
        """A CSV the page's commands wrote, by its columns' names."""
        if name not in self.tables:
            self.tables[name] = np.genfromtxt(self.folder / name, delimiter=',', names=True)
        return self.tables[name]


@dataclass(frozen=True)
class Claim:
    document: str
    pattern: str
    """A regular expression on the document's text, whitespace folded: one group per quoted number."""
    measured: Callable[[Ran], Sequence[float]]
    """The values those numbers quote, in the groups' order (several values to one group: each must hold)."""
    relative: float = 0.0
    bound: bool = False
    """The quoted numbers are upper bounds ("below 1e-6 m")."""

    def quoted(self) -> list[str]:
        text = ' '.join((REPO_ROOT / self.document).read_text(encoding='utf-8').split())
        match = re.search(self.pattern, text)
        if match is None:
            raise AssertionError(f'{self.document}: no longer says {self.pattern!r} (update test/doc_checks.py)')
        return list(match.groups())

    def problems(self, ran: Ran) -> list[str]:
        quoted, measured = self.quoted(), list(self.measured(ran))
        pairs = list(zip(quoted, measured)) if len(quoted) == len(measured) else [(quoted[0], value)
                                                                                   for value in measured]
        wrong = [(text, value) for text, value in pairs
                 if not (value < float(text) if self.bound else agrees(text, value, self.relative))]
        return [f'{self.document}: quotes {text} ({self.pattern!r}), the run gives {value:.6g}' for text, value in wrong]


def _after(data: np.ndarray, column: str, seconds: float) -> np.ndarray:
    return data[column][data['t'] >= seconds - 1e-9]


def _at(data: np.ndarray, column: str, seconds: float) -> float:
    return float(data[column][np.argmin(np.abs(data['t'] - seconds))])


def _peak_spin(data: np.ndarray) -> float:
    return float(max(np.abs(data[f'dphi{wheel}']).max() for wheel in range(1, 5)))


def _all_stick(data: np.ndarray) -> tuple[float, float]:
    """The first and last instant of the first stretch (after the start) in which no wheel slides."""
    sticking = np.all([data[f'slip{wheel}'] < 0.5 for wheel in range(1, 5)], axis=0)
    start = np.argmax(sticking & (data['t'] > 0.0))
    end = start + np.argmin(sticking[start:]) - 1
    return float(data['t'][start]), float(data['t'][end])


def _first_slip(data: np.ndarray, columns: Sequence[str]) -> list[float]:
    """``columns`` at the first instant a wheel slides."""
    first = np.argmax(np.any([data[f'slip{wheel}'] > 0.5 for wheel in range(1, 5)], axis=0))
    return [float(data[column][first]) for column in columns]


PAPER_CIRCLES = ('circle-belt.csv', 'circle-belt,non_lateral.csv', 'circle-belt,non_lateral,nonslip.csv')
PAPER_FIGURE8 = ('figure8-none.csv', 'figure8-belt.csv', 'figure8-belt,non_lateral.csv',
                 'figure8-belt,non_lateral,nonslip.csv')
HOLD_MOTORS = 'wallbot-sim motors hold.csv'
SLIP_MOTORS = 'wallbot-sim motors F_ad_400N.csv'

CLAIMS = (
    # docs/examples.md, the paper's runs
    Claim('docs/examples.md', r'trajectory task only tracks to below (\S+) m after 5 s',
          lambda ran: [_after(ran.csv('circle-none.csv'), 'err', 5.0).max()], bound=True),
    Claim('docs/examples.md', r'peak \|F_Y\| of about (\d+) N', lambda ran: [np.abs(ran.csv('circle-none.csv')['Fy']).max()]),
    Claim('docs/examples.md', r'every other set reaches below (\S+) m after 10 s',
          lambda ran: [_after(ran.csv(name), 'err', 10.0).max() for name in PAPER_CIRCLES], bound=True),
    Claim('docs/examples.md', r'stays on the path and on every constraint \(below (\S+) m\)',
          lambda ran: [max(ran.csv(name)['err'].max(), ran.csv(name)['residual'].max()) for name in PAPER_FIGURE8],
          bound=True),
    Claim('docs/examples.md', r'compromise stays about (\S+) m off',
          lambda ran: [_after(ran.csv('circle-inconsistent.csv'), 'err', 5.0).max()]),
    # docs/examples.md, wheel-wall contact
    Claim('docs/examples.md', r"holds: every wheel's use (\S+)",
          lambda ran: [ran.csv('hold.csv')[f'use{wheel}'][-1] for wheel in range(1, 5)]),
    Claim('docs/examples.md', r'slides at (\S+) m/s\^2',
          lambda ran: [np.polyfit(ran.csv('slide.csv')['t'], ran.csv('slide.csv')['vy'], 1)[0]]),
    Claim('docs/examples.md', r'at the worst heading \((\S+) degrees',
          lambda ran: [ran.number(HOLD_MOTORS, r'worst heading (\S+) deg')]),
    Claim('docs/examples.md', r'turning takes (\S+) N m on one side before the first wheel slides, against (\S+) N m',
          lambda ran: [ran.number(HOLD_MOTORS, r'turning \w+: (\S+) N m on the'),
                       ran.number(HOLD_MOTORS, r'steady speed: (\S+) N m per side')]),
    Claim('docs/examples.md', r'with gravity negligible the threshold is (\S+) N m',
          lambda ran: [ran.number(HOLD_MOTORS, r'gravity negligible: (\S+) N m')]),
    Claim('docs/examples.md', r'For the hold it gives the adhesion force needed, (\S+) N',
          lambda ran: [ran.number(HOLD_MOTORS, r'Adhesion needed: (\S+) N')]),
    # docs/examples.md, the closed loop that slips
    Claim('docs/examples.md', r'spin up to (\d+) rad/s at most; the robot is (\S+) mm off the path at 1.5 s and (\S+) mm',
          lambda ran: [_peak_spin(ran.csv('F_ad_400N.csv')), 1e3 * _at(ran.csv('F_ad_400N.csv'), 'err', 1.5),
                       1e3 * _at(ran.csv('F_ad_400N.csv'), 'err', 3.0)]),
    Claim('docs/examples.md', r'spins the wheels up \(to (\d+) rad/s',
          lambda ran: [_peak_spin(ran.csv('F_ad_300N.csv'))]),
    Claim('docs/examples.md', r'the error peaks at (\S+) m \(t = (\S+) s\)',
          lambda ran: [ran.csv('F_ad_300N.csv')['err'].max(),
                       ran.csv('F_ad_300N.csv')['t'][np.argmax(ran.csv('F_ad_300N.csv')['err'])]]),
    Claim('docs/examples.md', r'back on the path by 1.5 s \((\S+) mm\)',
          lambda ran: [1e3 * _at(ran.csv('F_ad_300N.csv'), 'err', 1.5)]),
    Claim('docs/examples.md', r'every wheel sticks from (\S+) s to (\S+) s',
          lambda ran: _all_stick(ran.csv('F_ad_300N.csv'))),
    Claim('docs/examples.md', r'drive the robot away: (\S+) m off at 1.5 s, (\S+) m at 3 s',
          lambda ran: [_at(ran.csv('F_ad_260N.csv'), 'err', 1.5), _at(ran.csv('F_ad_260N.csv'), 'err', 3.0)]),
    # docs/examples.md, the motor-limited climb into a wet patch
    Claim('docs/examples.md', r'the robot settles at (\S+) m/s', lambda ran: [_at(ran.csv('climb.csv'), 'vy', 0.5)]),
    Claim('docs/examples.md', r'each side applying (\S+) N m of the 2.2 N m commanded',
          lambda ran: [_at(ran.csv('climb.csv'), f'tau_{side}_applied', 0.5) for side in 'LR']),
    Claim('docs/examples.md', r'F_ad = (\d+) N from the chamber', lambda ran: [ran.csv('climb.csv')['F_ad'][0]]),
    Claim('docs/examples.md', r'with the centre at y = (\S+) m, and they slide from t = (\S+) s',
          lambda ran: _first_slip(ran.csv('climb.csv'), ('y', 't'))),
    Claim('docs/examples.md', r"adhesion force needed at (\S+) N at least \(its right front wheel, at (\S+) s",
          lambda ran: [ran.number(SLIP_MOTORS, r'Adhesion needed: (\S+) N \(right front wheel'),
                       ran.number(SLIP_MOTORS, r'friction binds at t = (\S+) s')]),
    Claim('docs/examples.md', r"its motors at the controller's (\d+) N m limit, above the (\S+) N m a turn",
          lambda ran: [ran.number(SLIP_MOTORS, r'Sizing: this run governs, (\S+) N m'),
                       ran.number(SLIP_MOTORS, r'turning \w+: (\S+) N m on the')]),
)


GRAPH_PAGES = (REPO_ROOT / 'README.md', REPO_ROOT / 'docs' / 'controller.md')
"""The pages whose blocks start the node graph (test_doc_graph_examples.py)."""
HEADLESS_PAGES = tuple(REPO_ROOT / 'docs' / name for name in ('examples.md', 'sweeps.md', 'driving.md', 'visualization.md'))
"""The pages whose blocks run without ROS (test_doc_examples.py, fast tier)."""


def claims_of(document: Path) -> list[Claim]:
    return [claim for claim in CLAIMS if REPO_ROOT / claim.document == document]


class DocumentRuns:
    """One page's bash blocks, run once for the class; a subclass names ``document``."""

    document: Path

    @pytest.fixture(scope='class')
    @classmethod
    def ran(cls, tmp_path_factory: pytest.TempPathFactory) -> Ran:
        folder = tmp_path_factory.mktemp(cls.document.stem)
        return Ran(folder, run_document(cls.document, folder))

    def test_every_block_runs(self, ran: Ran):
        failed = [f'{run.block.where} exited {run.returncode}:\n{run.output[-3000:]}'
                  for run in ran.runs if run.returncode != 0]
        assert not failed, '\n'.join(failed)
        assert len(ran.runs) == sum(block.runnable for block in blocks(self.document))

    def test_each_block_prints_what_the_page_shows(self, ran: Ran):
        wrong = [f'{run.block.where}: not printed (in this order, numbers agreeing):\n' + '\n'.join(missing)
                 + f'\n--- printed:\n{run.output[-3000:]}'
                 for run in ran.runs if run.block.output is not None
                 for missing in [missing_output(run.block.output, run.output)] if missing]
        assert not wrong, '\n'.join(wrong)

    def test_the_numbers_quoted_beside_the_commands_hold(self, ran: Ran):
        wrong = [problem for claim in claims_of(self.document) for problem in claim.problems(ran)]
        assert not wrong, '\n'.join(wrong)
