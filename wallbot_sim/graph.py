"""Child processes and the node graph as child processes: start each with its log, watch, stop in order.

Used by ``wallbot-sim run``, the tests and the benches. Every node runs as ``python -m MODULE
--ros-args ...`` in its own session (so a Ctrl-C at the terminal reaches only the launcher, which
then stops the nodes in order), with its output in ``LOG_DIR/NAME.log``.
"""

from __future__ import annotations

import ctypes
import functools
import os
import signal
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Mapping, Sequence


@dataclass(frozen=True)
class NodeSpec:
    """A node to start: a name for logs, its module, and its ROS parameters."""

    name: str
    module: str
    parameters: Mapping[str, object] = field(default_factory=dict)
    remaps: tuple[str, ...] = ()

    def command(self) -> list[str]:
        """The command line: the module run by this interpreter, with --ros-args."""
        args = [sys.executable, '-m', self.module, '--ros-args']
        for key, value in self.parameters.items():
            args += ['-p', f'{key}:={ros_value(value)}']
        for remap in self.remaps:
            args += ['-r', remap]
        return args


def ros_value(value: object) -> str:
    """A parameter value as --ros-args -p reads it (YAML)."""
    if isinstance(value, bool):
        return 'true' if value else 'false'
    if isinstance(value, float):
        return repr(value)
    if isinstance(value, (list, tuple)):
        return '[' + ','.join(ros_value(v) for v in value) + ']'
    return str(value)


class NodeDied(Exception):
    """A node of the graph exited while it should have been running."""

    def __init__(self, name: str, status: int, log: Path) -> None:
        super().__init__(f'node {name} exited with status {status}; its log: {log}')
        self.name, self.status, self.log = name, status, log


class ChildProcesses:
    """Child processes, each in a session of its own with its output in ``LOG_DIR/NAME.log``.

    The one way the project starts processes: ``wallbot-sim run``'s nodes (:class:`Graph`), the
    tests' ``process_runner`` and the benches. Its own session keeps a terminal's Ctrl-C away from
    a child (the parent stops its children in order); on Linux a child gets SIGTERM if the parent
    dies without stopping it. Stopping signals the child itself, SIGKILLs it after
    ``stop_timeout`` and then SIGKILLs whatever is left in its process group.
    """

    def __init__(self, log_dir: Path, env: Mapping[str, str], stop_timeout: float = 10.0) -> None:
        self.log_dir = Path(log_dir)
        self.env = dict(env)
        self.stop_timeout = stop_timeout
        self.processes: dict[str, subprocess.Popen] = {}
        """The newest process started under each name."""
        self._started: list[tuple[str, subprocess.Popen]] = []
        self.log_dir.mkdir(parents=True, exist_ok=True)

    def log(self, name: str) -> Path:
        """Where the process started as ``name`` writes its output."""
        return self.log_dir / f'{name}.log'

    def output(self, name: str) -> str:
        """Everything the process ``name`` has written so far."""
        return self.log(name).read_text(errors='replace')

    def start(self, command: Sequence[object], name: str, *, cwd: str | os.PathLike | None = None,
              env: Mapping[str, str] | None = None) -> subprocess.Popen:
        """Start ``command`` (each item as a string) as ``name``; ``env`` adds to the environment."""
        prctl = _prctl()  # resolved here: the child only calls it (no loader lock after the fork)
        with open(self.log(name), 'wb') as log:
            process = subprocess.Popen(
                [str(part) for part in command], stdout=log, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                cwd=cwd, env={**self.env, **(env or {})}, start_new_session=True,
                preexec_fn=None if prctl is None else lambda: prctl(_PR_SET_PDEATHSIG, int(signal.SIGTERM)))
        self.processes[name] = process
        self._started.append((name, process))
        return process

    def stop(self, process: subprocess.Popen) -> int | None:
        """SIGTERM ``process``, SIGKILL it after ``stop_timeout``, then SIGKILL what is left of its
        process group; its exit status (None if it could not be reaped)."""
        if process.poll() is None:
            _signal(process.pid, signal.SIGTERM)
            try:
                process.wait(self.stop_timeout)
            except subprocess.TimeoutExpired:
                _signal(process.pid, signal.SIGKILL)
                try:
                    process.wait(self.stop_timeout)
                except subprocess.TimeoutExpired:
                    pass
        _kill_group(process.pid)
        return process.returncode

    def stop_all(self, first: tuple[str, ...] = (), last: tuple[str, ...] = ()) -> None:
        """Signal every running process (:meth:`signal_all`) and wait for them (:meth:`wait_all`); those
        named in ``last`` (with SIGINT, in that order) only once the others have exited."""
        if last:
            self.signal_all(first, keep=last)
            self.wait_all(keep=last)
        self.signal_all((*first, *last))
        self.wait_all()

    def signal_all(self, first: tuple[str, ...] = (), keep: tuple[str, ...] = ()) -> None:
        """Signal every running process but those named in ``keep``: those named in ``first`` with SIGINT
        (in that order), then the rest with SIGTERM, newest first, without waiting: each node needs a few
        hundred milliseconds to leave DDS, and one after another the launcher would take seconds to stop."""
        named = [process for name in first for started, process in self._started if started == name]
        rest = [process for name, process in reversed(self._started) if name not in first and name not in keep]
        for process in named + rest:
            if process.poll() is None:
                _signal(process.pid, signal.SIGINT if process in named else signal.SIGTERM)

    def wait_all(self, keep: tuple[str, ...] = ()) -> None:
        """Wait up to ``stop_timeout`` for every process but those named in ``keep`` to exit; SIGKILL
        whatever is left, and what is left of their process groups. Their exit statuses stay in
        :attr:`processes`."""
        deadline = time.monotonic() + self.stop_timeout
        for name, process in self._started:
            if name in keep:
                continue
            try:
                process.wait(max(0.0, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                _signal(process.pid, signal.SIGKILL)
                process.wait()
            _kill_group(process.pid)
        # reaped: their ids may belong to other processes from now on
        self._started = [(name, process) for name, process in self._started if name in keep]


class Graph(ChildProcesses):
    """The nodes of a graph as child processes, started in order and stopped together."""

    def start_node(self, spec: NodeSpec) -> subprocess.Popen:
        """Start the node ``spec`` describes, its output in ``LOG_DIR/NAME.log``."""
        return self.start(spec.command(), spec.name)


def child_processes(pid: int) -> dict[int, str]:
    """The live children of process ``pid`` with their command lines (Linux /proc)."""
    found = {}
    for entry in Path('/proc').iterdir():
        if entry.name.isdigit():
            try:
                if int((entry / 'stat').read_text().rsplit(')', 1)[1].split()[1]) == pid:
                    found[int(entry.name)] = (entry / 'cmdline').read_bytes().replace(b'\0', b' ').decode()
            except (OSError, IndexError, ValueError):  # gone meanwhile, or not ours to read
                continue
    return found


def cpu_seconds(pid: int) -> float:
    """CPU time (utime + stime, s) process ``pid`` has used so far (Linux /proc)."""
    fields = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


def resident_mib(pid: int) -> float:
    """Resident memory (VmRSS) of process ``pid`` in MiB; NaN if it does not say."""
    for line in Path(f'/proc/{pid}/status').read_text().splitlines():
        if line.startswith('VmRSS:'):
            return int(line.split()[1]) / 1024.0
    return float('nan')


_PR_SET_PDEATHSIG = 1


@functools.cache
def _prctl() -> Callable[..., int] | None:
    """libc's prctl on Linux (None elsewhere)."""
    return ctypes.CDLL(None).prctl if sys.platform.startswith('linux') else None


def _signal(pid: int, sig: int) -> None:
    try:
        os.kill(pid, sig)
    except ProcessLookupError:
        pass


def _kill_group(pid: int) -> None:
    """SIGKILL what is left of the process group ``pid`` leads (children it started in it)."""
    try:
        os.killpg(pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        pass
