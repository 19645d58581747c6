"""Every bench script still starts: it imports what it uses and parses its arguments.

The benches are run by hand, not by the suite, so a refactor that renames what one imports would
otherwise go unnoticed until someone measures.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

BENCH = Path(__file__).resolve().parents[1] / 'bench'


@pytest.mark.parametrize('script', sorted(BENCH.glob('bench_*.py')), ids=lambda p: p.name)
def test_bench_script_starts(script: Path):
    result = subprocess.run([sys.executable, str(script), '--help'], capture_output=True, text=True, timeout=120,
                            cwd=BENCH)
    assert result.returncode == 0, result.stderr[-2000:]
    assert result.stdout.startswith('usage: '), result.stdout[:200]
