"""Running ``wallbot-sim`` as a user does, in a child process, and reading what it wrote (shared by the CLI tests)."""

from __future__ import annotations

import csv
import re
import subprocess
import sys
import time
from pathlib import Path

WALLBOT = [sys.executable, '-m', 'wallbot_sim.cli.main']
"""The command line of ``wallbot-sim`` in this interpreter."""


def wallbot(*args: object, timeout: float = 180.0) -> subprocess.CompletedProcess:
    """``wallbot-sim ARGS`` to its end, output captured."""
    return subprocess.run([*WALLBOT, *map(str, args)], capture_output=True, text=True, timeout=timeout)


def simulate(*args: object) -> subprocess.CompletedProcess:
    """``wallbot-sim simulate ARGS`` to its end, output captured."""
    return wallbot('simulate', *args)


def read_csv(path: str | Path) -> tuple[list[str], list[list[float]]]:
    """The header and the rows (as floats) of a CSV that ``simulate`` wrote."""
    with open(path, newline='') as stream:
        rows = list(csv.reader(stream))
    return rows[0], [[float(v) for v in row] for row in rows[1:]]


def assert_one_line_error(result: subprocess.CompletedProcess, *fragments: str) -> None:
    """The command failed with one line on stderr, no traceback, holding every fragment."""
    assert result.returncode != 0
    assert 'Traceback' not in result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    for fragment in fragments:
        assert fragment in lines[0]


def wait_for_output(process_runner, name: str, pattern: str, timeout: float) -> re.Match:
    """The first match of ``pattern`` in what ``name`` wrote, once it is there (failing if the
    process exits or ``timeout`` passes first)."""
    deadline = time.monotonic() + timeout
    while True:
        found = re.search(pattern, process_runner.output(name), re.MULTILINE)
        if found:
            return found
        assert process_runner.processes[name].poll() is None, process_runner.output(name)
        assert time.monotonic() < deadline, f'no {pattern!r} from {name}: ' + process_runner.output(name)
        time.sleep(0.1)
