"""The node graph as child processes: start each node with its parameters, watch, stop in order.

Used by ``wallbot-sim run``. Every node runs as ``python -m MODULE --ros-args ...`` in its own
session (so a Ctrl-C at the terminal reaches only the launcher, which then stops the nodes in
order), with its output in ``LOG_DIR/NAME.log``.
"""

from __future__ import annotations

import ctypes
import os
import signal
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Mapping


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


class Graph:
    """Child node processes, started in order and stopped in reverse (or as asked)."""

    def __init__(self, log_dir: Path, env: Mapping[str, str]) -> None:
        self.log_dir = log_dir
        self.env = dict(env)
        self.processes: dict[str, subprocess.Popen] = {}
        log_dir.mkdir(parents=True, exist_ok=True)

    def log(self, name: str) -> Path:
        """Where node ``name`` writes its output."""
        return self.log_dir / f'{name}.log'

    def start(self, spec: NodeSpec) -> None:
        with open(self.log(spec.name), 'wb') as log:
            self.processes[spec.name] = subprocess.Popen(
                spec.command(), stdout=log, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                env=self.env, start_new_session=True, preexec_fn=_end_with_parent)

    def check(self) -> None:
        """Raise NodeDied for the first node that has exited."""
        for name, process in self.processes.items():
            status = process.poll()
            if status is not None:
                raise NodeDied(name, status, self.log(name))

    def stop_all(self, first: tuple[str, ...] = (), timeout: float = 10.0) -> None:
        """Signal every running node (:meth:`signal_all`) and wait for them (:meth:`wait_all`)."""
        self.signal_all(first)
        self.wait_all(timeout)

    def signal_all(self, first: tuple[str, ...] = ()) -> None:
        """Signal every running node, ``first`` with SIGINT (in that order) and then the rest with
        SIGTERM, without waiting: each node needs a few hundred milliseconds to leave DDS, and one
        after another the launcher would take seconds to stop."""
        order = [*first, *(name for name in reversed(list(self.processes)) if name not in first)]
        for name in order:
            process = self.processes.get(name)
            if process is not None and process.poll() is None:
                _signal(process, signal.SIGINT if name in first else signal.SIGTERM)

    def wait_all(self, timeout: float = 10.0) -> None:
        """Wait for every node to exit; SIGKILL whatever is left after ``timeout``."""
        deadline = time.monotonic() + timeout
        for process in self.processes.values():
            try:
                process.wait(max(0.0, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                _signal(process, signal.SIGKILL)
                process.wait()


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


def resident_mib(pid: int) -> float:
    """Resident memory (VmRSS) of process ``pid`` in MiB; NaN if it does not say."""
    for line in Path(f'/proc/{pid}/status').read_text().splitlines():
        if line.startswith('VmRSS:'):
            return int(line.split()[1]) / 1024.0
    return float('nan')


def _end_with_parent() -> None:
    """In the child: have Linux send SIGTERM if the launcher dies without stopping the graph."""
    if sys.platform.startswith('linux'):
        ctypes.CDLL(None).prctl(_PR_SET_PDEATHSIG, signal.SIGTERM)


_PR_SET_PDEATHSIG = 1


def _signal(process: subprocess.Popen, sig: int) -> None:
    try:
        os.killpg(process.pid, sig)
    except ProcessLookupError:
        pass
