"""Start-up of the commands a user waits on (a measurement, not a test).

  * ``wallbot-sim run circle --duration 1 --no-plots`` (the numba engine, its kernel in numba's cache): the whole
    command's wall time, the wall time to the dynamics' first step, and the CPU seconds of every process; per
    process, when it started, when it was in business (the dynamics' first step, the recorder recording, the
    trajectory node's first plan, the constraint set out) and its CPU seconds. Beside it the same command on the
    python engine (``--engine python``: no kernel to load), the baseline.
  * Each process's load alone: ``python -c 'import MODULE'`` for the launcher's verb and each node's module, and
    the kernel's load from numba's cache, beside ``python -c pass``.
  * ``wallbot-sim sweep`` of 8 robots x 2 s: in one chunk (this process computes it) and in two (a local Dask
    cluster of two workers), with and without figures; and pointed at an unreachable scheduler
    (``--scheduler tcp://127.0.0.1:1``): its wall time, its lines on the terminal and what it left behind.

Every command runs ``--rounds`` times, the variants in turn (so a change of the machine's load falls on all of
them), and the tables give the shortest and the median. ``--against TREE`` runs every command a second time with
TREE first on PYTHONPATH (another checkout of the package, e.g. the commit before a change), in turn with this
tree's, and gives the ratios this tree / TREE.

``--realtime`` runs the bench and every command it starts at a real-time priority (SCHED_RR, root only): above
every other job on the machine, the commands have the cores to themselves as on a quiet machine (one engineer's
figures on a machine several share).

    python bench/bench_startup.py [--rounds 3] [--against TREE] [--only run,imports,sweep] [--realtime]
                                  [--write-docs [FILE]]
"""

from __future__ import annotations

import argparse
import os
import re
import resource
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Sequence

from report import Report, add_write_docs_option
from wallbot_sim.graph import child_processes, cpu_seconds

REPO = Path(__file__).resolve().parents[1]
RUN = ('run', 'circle', '--duration', '1', '--no-plots')
IN_BUSINESS = {'wallbot_sim.nodes.dynamics_recorder': ('dynamics', 'starting with constraints'),
               'wallbot_sim.nodes.dynamics': ('dynamics', 'starting with constraints'),
               'wallbot_sim.nodes.recorder': ('recorder', 'recording '),
               'wallbot_sim.nodes.trajectory': ('trajectory', 'plan circle from'),
               'wallbot_sim.nodes.constraint_config': ('constraint_config', 'constraints: ')}
"""Per node module: the logger whose line says the process is in business, and how that line begins."""
FIRST_STEP = IN_BUSINESS['wallbot_sim.nodes.dynamics_recorder']
IMPORTS = {'launcher (run)': 'import wallbot_sim.cli.main, wallbot_sim.cli.run',
           'dynamics_recorder': 'import wallbot_sim.nodes.dynamics_recorder',
           'trajectory': 'import wallbot_sim.nodes.trajectory',
           'constraint_config': 'import wallbot_sim.nodes.constraint_config',
           "the kernel from numba's cache": "from wallbot_sim.model.compiled import compile_run; compile_run('ideal')",
           'python -c pass (baseline)': 'pass'}
"""What each process loads before it does anything, as ``python -c`` code."""
SWEEP_SPEC = """scenario: figure8
constraints: belt,non_lateral,nonslip
contact: ideal
controller: false
grid:
  adhesion_force: [150.0]
vary:
  body_mass: [6.0, 12.0]
  com_height: [0.03, 0.08]
samples: 8
seed: 1
duration: 2.0
chunk_size: {chunk_size}
"""
UNREACHABLE = 'tcp://127.0.0.1:1'
REALTIME_PRIORITY = 10
"""SCHED_RR priority of ``--realtime`` (1-99; the kernel's own real-time threads run at 50 and above)."""
LOG_TIME = re.compile(r'^\[\w+\] \[(\d+\.\d+)\] \[wallbot\.(\w+)\]: (.*)$')


@dataclass
class Process:
    """A child process of a timed command, as seen in /proc while it ran."""

    command: str
    started: float
    """Wall time (epoch s) it started."""
    cpu: float = 0.0
    """CPU seconds at the last look."""

    @property
    def module(self) -> str:
        match = re.search(r' -m (\S+)', self.command)
        return match.group(1) if match else self.command.split(' ')[0]


@dataclass
class Timing:
    """One command's run."""

    wall: float
    cpu: float
    """CPU seconds of the command and every child it waited for."""
    status: int
    stderr: str
    started: float
    """Wall time (epoch s) the command was started."""
    processes: list[Process] = field(default_factory=list)


def boot_time() -> float:
    """The wall time (epoch s) of the machine's boot, as /proc/PID/stat's start times count from it."""
    return time.time() - float(Path('/proc/uptime').read_text().split()[0])


def process_start(pid: int, booted: float) -> float:
    """Wall time (epoch s, 10 ms resolution) process ``pid`` started."""
    fields = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()
    return booted + int(fields[19]) / os.sysconf('SC_CLK_TCK')


def timed(command: Sequence[str], env: dict[str, str], cwd: Path, poll: float = 0.02) -> Timing:
    """Run ``command`` in ``cwd`` to its end, looking at its children every ``poll`` s."""
    booted = boot_time()
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    started, t0 = time.time(), time.monotonic()
    process = subprocess.Popen(command, env=env, cwd=cwd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    seen: dict[int, Process] = {}
    stderr: list[str] = []
    reader = _drain(process, stderr)
    while process.poll() is None:
        for pid, line in child_processes(process.pid).items():
            try:
                if pid not in seen:
                    seen[pid] = Process(line.strip(), process_start(pid, booted))
                if line.strip():  # a first look may come between its fork and its exec; a zombie has none
                    seen[pid].command = line.strip()
                seen[pid].cpu = cpu_seconds(pid)
            except (OSError, IndexError, ValueError):  # gone meanwhile
                continue
        time.sleep(poll)
    wall = time.monotonic() - t0
    reader.join()
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return Timing(wall, cpu, process.returncode, ''.join(stderr), started, list(seen.values()))


def _drain(process: subprocess.Popen, into: list[str]) -> threading.Thread:
    thread = threading.Thread(target=lambda: into.append(process.stderr.read()), daemon=True)
    thread.start()
    return thread


def log_lines(logs: Path) -> list[tuple[float, str, str]]:
    """Every node's log line under ``logs``: (wall time, logger, text)."""
    found = []
    for log in sorted(logs.glob('*.log')):
        for line in log.read_text(errors='replace').splitlines():
            match = LOG_TIME.match(line)
            if match:
                found.append((float(match.group(1)), match.group(2), match.group(3)))
    return found


def first_line(lines: list[tuple[float, str, str]], logger: str, begins: str) -> float | None:
    return min((t for t, name, text in lines if name == logger and text.startswith(begins)), default=None)


@dataclass(frozen=True)
class Tree:
    """A checkout whose package the commands run (first on PYTHONPATH). They run in the bench's scratch directory:
    ``python -m`` and ``-c`` put the working directory first on sys.path, which in a checkout would run its package
    instead of the tree's."""

    label: str
    path: Path

    def env(self) -> dict[str, str]:
        return {**os.environ, 'PYTHONPATH': str(self.path)}


def wallbot(*args: str) -> list[str]:
    return [sys.executable, '-m', 'wallbot_sim.cli.main', *args]


def cell(values: Sequence[float], digits: int = 2) -> str:
    """The shortest and the median of ``values``."""
    if not values:
        return 'n/a'
    return f'{min(values):.{digits}f} / {statistics.median(values):.{digits}f}'


def ratio(numerator: Sequence[float], denominator: Sequence[float]) -> str:
    if not numerator or not denominator:
        return 'n/a'
    return f'**{statistics.median(numerator) / statistics.median(denominator):.2f}**'


# --- run -----------------------------------------------------------------------------------------------
@dataclass
class RunFigures:
    """A variant of ``run`` over the rounds."""

    wall: list[float] = field(default_factory=list)
    first_step: list[float] = field(default_factory=list)
    cpu: list[float] = field(default_factory=list)
    per_process: dict[str, dict[str, list[float]]] = field(default_factory=dict)

    def add(self, timing: Timing, out: Path) -> None:
        if timing.status != 0:
            print(f'  failed ({timing.status}): {timing.stderr.strip().splitlines()[-1:]}', file=sys.stderr)
            return
        lines = log_lines(out / 'logs')
        step = first_line(lines, *FIRST_STEP)
        self.wall.append(timing.wall)
        self.cpu.append(timing.cpu)
        if step is not None:
            self.first_step.append(step - timing.started)
        launcher = self.per_process.setdefault('launcher (wallbot-sim run)', {})
        launcher.setdefault('started', []).append(0.0)
        for process in timing.processes:
            name = process.module.rsplit('.', 1)[-1]
            figures = self.per_process.setdefault(name, {})
            figures.setdefault('started', []).append(process.started - timing.started)
            figures.setdefault('cpu', []).append(process.cpu)
            logger, begins = IN_BUSINESS.get(process.module, (None, None))
            at = first_line(lines, logger, begins) if logger else None
            if at is not None:
                figures.setdefault('in business', []).append(at - timing.started)
        launcher.setdefault('cpu', []).append(timing.cpu - sum(p.cpu for p in timing.processes))


def measure_run(trees: Sequence[Tree], rounds: int, work: Path, report: Report) -> None:
    variants = [(tree, engine) for tree in trees for engine in ('numba', 'python')]
    figures = {variant: RunFigures() for variant in variants}
    for round_ in range(rounds):
        for tree, engine in variants:
            out = work / f'run-{tree.label}-{engine}-{round_}'
            timing = timed(wallbot(*RUN, '--engine', engine, '--out', str(out)), tree.env(), work)
            figures[tree, engine].add(timing, out)
            print(f'run {tree.label} {engine} round {round_ + 1}: {timing.wall:.2f} s wall, {timing.cpu:.2f} s CPU '
                  f'(load {os.getloadavg()[0]:.1f})', flush=True)
    rows = []
    for tree, engine in variants:
        f = figures[tree, engine]
        rows.append((f'{tree.label}, engine {engine}', cell(f.wall), cell(f.first_step), cell(f.cpu)))
    for tree in trees:
        numba, python = figures[tree, 'numba'], figures[tree, 'python']
        rows.append((f'{tree.label}: numba / python', ratio(numba.wall, python.wall),
                     ratio(numba.first_step, python.first_step), ratio(numba.cpu, python.cpu)))
    if len(trees) == 2:
        for engine in ('numba', 'python'):
            this, other = figures[trees[0], engine], figures[trees[1], engine]
            rows.append((f'engine {engine}: {trees[0].label} / {trees[1].label}', ratio(this.wall, other.wall),
                         ratio(this.first_step, other.first_step), ratio(this.cpu, other.cpu)))
    report.table(('`wallbot-sim ' + ' '.join(RUN) + '`', 'whole command (s)', 'to the first step (s)',
                  'CPU s, every process'), rows,
                 f'`run` as a user starts it, {rounds} times each in turn (shortest / median; ratios of the medians):')
    for tree in trees:
        f = figures[tree, 'numba']
        report.table(('process', 'started (s after the command)', 'in business (s after the command)', 'CPU s'),
                     [(name, cell(values.get('started', [])), cell(values.get('in business', [])),
                       cell(values.get('cpu', []))) for name, values in f.per_process.items()],
                     f'Each process of the numba run, {tree.label} (shortest / median; in business: the first step, '
                     'recording, the first plan, the constraint set out):')


# --- imports -------------------------------------------------------------------------------------------
def measure_imports(trees: Sequence[Tree], rounds: int, work: Path, report: Report) -> None:
    walls: dict[tuple[str, str], list[float]] = {}
    for round_ in range(rounds):
        for tree in trees:
            for name, code in IMPORTS.items():
                t0 = time.monotonic()
                subprocess.run([sys.executable, '-c', code], env=tree.env(), cwd=work, check=True)
                walls.setdefault((tree.label, name), []).append(time.monotonic() - t0)
        print(f'imports round {round_ + 1} (load {os.getloadavg()[0]:.1f})', flush=True)
    header = ['what a process loads', *(f'{tree.label}: wall s' for tree in trees)]
    if len(trees) == 2:
        header.append(f'{trees[0].label} / {trees[1].label}')
    rows = []
    for name in IMPORTS:
        row = [name, *(cell(walls[tree.label, name]) for tree in trees)]
        if len(trees) == 2:
            row.append(ratio(walls[trees[0].label, name], walls[trees[1].label, name]))
        rows.append(row)
    report.table(header, rows, "Each process's load alone, `python -c CODE` to its end (shortest / median):")


# --- sweep ---------------------------------------------------------------------------------------------
def measure_sweep(trees: Sequence[Tree], rounds: int, work: Path, report: Report) -> None:
    specs = {}
    for chunk_size in (8, 4):
        specs[chunk_size] = work / f'sweep-{chunk_size}.yaml'
        specs[chunk_size].write_text(SWEEP_SPEC.format(chunk_size=chunk_size), encoding='utf-8')
    variants: dict[str, Callable[[Path], list[str]]] = {
        '8 robots x 2 s, one chunk': lambda out: wallbot('sweep', str(specs[8]), '--out', str(out)),
        '... without figures': lambda out: wallbot('sweep', str(specs[8]), '--out', str(out), '--no-figures'),
        'two chunks (a local cluster of 2 workers), without figures':
            lambda out: wallbot('sweep', str(specs[4]), '--out', str(out), '--no-figures'),
        f'--scheduler {UNREACHABLE} (unreachable)':
            lambda out: wallbot('sweep', str(specs[8]), '--out', str(out), '--scheduler', UNREACHABLE),
    }
    walls: dict[tuple[str, str], list[float]] = {}
    cpus: dict[tuple[str, str], list[float]] = {}
    outcome: dict[tuple[str, str], str] = {}
    for round_ in range(rounds):
        for tree in trees:
            for index, (name, command) in enumerate(variants.items()):
                out = work / f'sweep-{tree.label}-{round_}-{index}'  # a fresh directory: a used one would resume
                timing = timed(command(out), tree.env(), work)
                walls.setdefault((tree.label, name), []).append(timing.wall)
                cpus.setdefault((tree.label, name), []).append(timing.cpu)
                lines = [line for line in timing.stderr.splitlines() if line.strip() and not line.startswith('  ')]
                unexpected = [line for line in lines if not line.startswith(('sweep:', 'wrote ', 'wallbot-sim sweep'))]
                outcome[tree.label, name] = (f'exit {timing.status}, {len(unexpected)} other lines'
                                             + (', output left behind' if out.exists() and timing.status else ''))
                said = ''.join(f'\n    {line}' for line in (unexpected or lines[-1:] if timing.status else unexpected))
                print(f'sweep {tree.label} {name} round {round_ + 1}: {timing.wall:.2f} s, {timing.cpu:.2f} s CPU '
                      f'({outcome[tree.label, name]}; load {os.getloadavg()[0]:.1f}){said}', flush=True)
    header = ['`wallbot-sim sweep`', *(f'{tree.label}: wall s' for tree in trees),
              *(f'{tree.label}: CPU s, every process' for tree in trees), *(f'{tree.label}: outcome' for tree in trees)]
    if len(trees) == 2:
        header += [f'wall: {trees[0].label} / {trees[1].label}', f'CPU: {trees[0].label} / {trees[1].label}']
    rows = []
    for name in variants:
        row = [name, *(cell(walls[tree.label, name]) for tree in trees),
               *(cell(cpus[tree.label, name]) for tree in trees), *(outcome[tree.label, name] for tree in trees)]
        if len(trees) == 2:
            row += [ratio(walls[trees[0].label, name], walls[trees[1].label, name]),
                    ratio(cpus[trees[0].label, name], cpus[trees[1].label, name])]
        rows.append(row)
    report.table(header, rows, 'Sweeps, whole commands (shortest / median; other lines: on stderr besides the '
                               "verb's own, such as a library's warning):")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--rounds', type=int, default=3, help='times each command runs (in turn with the others)')
    parser.add_argument('--against', metavar='TREE', help='another checkout to compare with (run first on PYTHONPATH)')
    parser.add_argument('--only', default='run,imports,sweep', help='which of run, imports, sweep to measure')
    parser.add_argument('--realtime', action='store_true',
                        help='run every command at a real-time priority, above the machine\'s other jobs (root only)')
    add_write_docs_option(parser)
    args = parser.parse_args()
    if args.realtime:  # the commands inherit it
        os.sched_setscheduler(0, os.SCHED_RR, os.sched_param(REALTIME_PRIORITY))
    parts = set(args.only.split(','))
    if parts - {'run', 'imports', 'sweep'}:
        parser.error(f'--only takes run, imports and sweep, got {args.only!r}')
    trees = [Tree('this tree', REPO)]
    if args.against:
        trees.append(Tree(Path(args.against).resolve().name, Path(args.against).resolve()))
    report = Report('startup')
    print(f'{os.cpu_count()} cores; load average {os.getloadavg()[0]:.1f}', flush=True)
    with tempfile.TemporaryDirectory(prefix='bench_startup-') as work:
        if 'imports' in parts:
            measure_imports(trees, args.rounds, Path(work), report)
        if 'run' in parts:
            measure_run(trees, args.rounds, Path(work), report)
        if 'sweep' in parts:
            measure_sweep(trees, args.rounds, Path(work), report)
    for table in report.tables:
        print('\n' + table.markdown())
    report.write(args.write_docs)
    return 0


if __name__ == '__main__':
    sys.exit(main())
