"""The documentation's command blocks, read and run (docs/architecture.md, "The documentation").

A ```` ```bash ```` block runs as written, from a scratch folder standing for the repository root
(``config/`` and ``examples/`` linked in), each block of a page after the ones before it. A
```` ```console ```` block is not run, and says why on the line before its fence::

    <!-- not run: a ROS 2 Jazzy install (ros2cli) -->

A bash block may be run shorter than written only where nothing the text quotes depends on it,
said the same way (every ``OLD`` in the block becomes ``NEW``)::

    <!-- in the suite: --duration 3 as --duration 0.5 (nothing quoted depends on the duration) -->

A ```` ```text ```` block right after a bash block is what that block prints: each of its lines but
``...`` must be printed, in that order, its numbers within ``agrees``' tolerance.

Used by test/test_doc_examples.py and docs/make_figures.py.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from dataclasses import dataclass, field
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parents[1]
DOCUMENTS = (REPO_ROOT / 'README.md', *sorted((REPO_ROOT / 'docs').glob('*.md')))
LINKED = ('config', 'examples')
"""What the blocks read from the repository root, linked into the scratch folder."""
BLOCK_TIMEOUT = 900.0
"""Seconds a block may take before it counts as stalled (a stall guard, not a timing assertion)."""

FENCED = re.compile(r'(?:^<!-- (?P<note>.*?) -->\n)?^```(?P<kind>\w*)\n(?P<body>.*?)^```\n', re.DOTALL | re.MULTILINE)
NOT_RUN = re.compile(r'not run: (?P<reason>\S.*)')
SHORTENED = re.compile(r'in the suite: (?P<old>.+?) as (?P<new>.+?) \((?P<reason>[^)]+)\)')
COMMAND_MARK = '\x1e$ '
"""Starts the line the runner prints before each command of a block, so that output is known by command."""
NUMBER = re.compile(r'[-+]?\d+(?:\.\d+)?(?:e[-+]?\d+)?')
RUN_SPECIFIC = re.compile(r'(ROS_DOMAIN_ID[= ])\d+')
"""Numbers that differ from run to run by design: the DDS domain each run claims."""

PRELUDE = f"""\
set -euo pipefail
wallbot-sim() {{ command wallbot-sim "$@" || exit $?; }}
python() {{ command python "$@" || exit $?; }}
trap 'printf "{COMMAND_MARK}%s\\n" "$BASH_COMMAND"' DEBUG
"""
"""Before each block: any failing command fails the block (also inside ``a && b``), each command marked."""


@dataclass(frozen=True)
class Block:
    document: Path
    line: int
    kind: str
    body: str
    note: str
    output: str | None
    """The ``text`` block right after this one, if any: what it prints."""

    @property
    def where(self) -> str:
        return f'{self.document.relative_to(REPO_ROOT)}:{self.line}'

    @property
    def not_run_reason(self) -> str | None:
        match = NOT_RUN.fullmatch(self.note)
        return match.group('reason') if match else None

    @property
    def runnable(self) -> bool:
        return self.kind == 'bash'

    def script(self) -> str:
        """The block as the suite runs it: as written, or shortened as its note says."""
        match = SHORTENED.fullmatch(self.note)
        if not match:
            return self.body
        if match.group('old') not in self.body:
            raise ValueError(f'{self.where}: its note shortens {match.group("old")!r}, which the block lacks')
        return self.body.replace(match.group('old'), match.group('new'))


def blocks(document: Path) -> list[Block]:
    """Every fenced block of ``document`` with the note before it and (for a command) the output after it."""
    text = document.read_text(encoding='utf-8')
    found = [(match, text[:match.start('kind')].count('\n') + 1) for match in FENCED.finditer(text)]
    result = []
    for index, (match, line) in enumerate(found):
        after = found[index + 1][0] if index + 1 < len(found) else None
        output = None
        if after is not None and after.group('kind') == 'text' and after.start() == match.end():
            output = after.group('body')
        result.append(Block(document, line, match.group('kind'), match.group('body'), match.group('note') or '',
                            output))
    return result


@dataclass
class BlockRun:
    block: Block
    returncode: int
    output: str
    """stdout and stderr as one stream, each command's output after its mark."""
    commands: dict[str, str] = field(default_factory=dict)
    """Each command as written (variables unexpanded) -> what it printed (the last run of it, in a loop)."""

    def printed_by(self, command: str) -> str:
        """What the one command containing ``command`` printed."""
        matching = [text for written, text in self.commands.items() if command in written]
        if len(matching) != 1:
            raise KeyError(f'{self.block.where}: {len(matching)} commands contain {command!r}')
        return matching[0]


def scratch_root(folder: Path) -> Path:
    """``folder`` made to stand for the repository root: what the blocks read linked in."""
    folder.mkdir(parents=True, exist_ok=True)
    for name in LINKED:
        link = folder / name
        if not link.exists():
            link.symlink_to(REPO_ROOT / name, target_is_directory=True)
    return folder


def block_environment() -> dict[str, str]:
    """This environment with this interpreter's ``bin/`` (its ``wallbot-sim``) first on PATH, the package importable."""
    bin_dir = str(Path(sys.executable).parent)
    python_path = os.pathsep.join(filter(None, (str(REPO_ROOT), os.environ.get('PYTHONPATH'))))
    return {**os.environ, 'PATH': os.pathsep.join((bin_dir, os.environ.get('PATH', ''))), 'PYTHONPATH': python_path,
            'PYTHONUNBUFFERED': '1', 'MPLBACKEND': 'Agg'}


def run_block(block: Block, folder: Path, env: dict[str, str]) -> BlockRun:
    process = subprocess.run(['bash', '-c', PRELUDE + block.script()], cwd=folder, env=env, stdout=subprocess.PIPE,
                             stderr=subprocess.STDOUT, text=True, timeout=BLOCK_TIMEOUT)
    run = BlockRun(block, process.returncode, process.stdout)
    current = None
    for line in process.stdout.split('\n'):
        if line.startswith(COMMAND_MARK):
            current = line[len(COMMAND_MARK):]
            run.commands[current] = ''
        elif current is not None:
            run.commands[current] += line + '\n'
    return run


def run_document(document: Path, folder: Path, until: int | None = None) -> list[BlockRun]:
    """Run the bash blocks of ``document`` in order in ``folder`` (up to the one at line ``until``); stop at the
    first that fails."""
    env = block_environment()
    runs = []
    for block in blocks(document):
        if not block.runnable or (until is not None and block.line > until):
            continue
        runs.append(run_block(block, scratch_root(folder), env))
        if runs[-1].returncode != 0:
            break
    return runs


def printed_lines(output: str) -> list[str]:
    """The lines a terminal would show last: progress lines rewritten with carriage returns kept apart."""
    return [part.rstrip() for line in output.split('\n') if not line.startswith(COMMAND_MARK)
            for part in line.split('\r') if part.strip()]


def agrees(quoted: str, measured: float, relative: float = 0.0) -> bool:
    """A quoted number holds when the measured value is within one unit of its last quoted digit (0.989: 0.988 to
    0.990; 119: 118 to 120), or within ``relative`` of it where a claim says so."""
    value = float(quoted)
    mantissa = quoted.lower().split('e')[0]
    decimals = len(mantissa.partition('.')[2])
    exponent = int(quoted.lower().split('e')[1]) if 'e' in quoted.lower() else 0
    unit = 10.0 ** (exponent - decimals)
    return abs(measured - value) <= max(unit * (1 + 1e-9), relative * abs(value))


def _shape(line: str) -> tuple[str, list[str]]:
    line = RUN_SPECIFIC.sub(r'\1#', line)
    return NUMBER.sub('#', ' '.join(line.split())), NUMBER.findall(line)


def missing_output(expected: str, output: str) -> list[str]:
    """The expected lines (``...``: any lines) not printed in that order with their numbers in agreement."""
    printed = [_shape(line) for line in printed_lines(output)]
    missing, position = [], 0
    for line in expected.splitlines():
        if line.strip() in ('', '...'):
            continue
        shape, numbers = _shape(line)
        for index in range(position, len(printed)):
            if printed[index][0] == shape and all(agrees(quoted, float(got))
                                                  for quoted, got in zip(numbers, printed[index][1])):
                position = index + 1
                break
        else:
            missing.append(line)
    return missing
