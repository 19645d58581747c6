"""Every bench script still starts (it imports what it uses and parses its arguments), and writes its
figures into its section of docs/performance.md.

The benches are run by hand, not by the suite, so a refactor that renames what one imports would
otherwise go unnoticed until someone measures.
"""

from __future__ import annotations

import importlib.util
import os
import re
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


def test_every_bench_script_can_write_its_figures_into_the_docs():
    missing = [script.name for script in sorted(BENCH.glob('bench_*.py'))
               if '--write-docs' not in script.read_text(encoding='utf-8')]
    assert not missing, f'bench scripts without --write-docs: {missing}'


def load_report_module():
    """bench/report.py (the benches import it from their own folder, which is not a package)."""
    if 'bench_report' not in sys.modules:
        spec = importlib.util.spec_from_file_location('bench_report', BENCH / 'report.py')
        module = importlib.util.module_from_spec(spec)
        sys.modules[spec.name] = module  # dataclasses look their module up there
        spec.loader.exec_module(module)
    return sys.modules['bench_report']


def test_a_section_is_replaced_in_place_and_a_new_one_appended():
    report = load_report_module()
    text = ('# Doc\n\n<!-- bench:a -->\nold a\n<!-- /bench:a -->\n\nbetween\n\n'
            '<!-- bench:ab -->\nold ab\n<!-- /bench:ab -->\n\nafter\n')
    replaced = report.replace_section(text, 'a', 'new a')
    assert replaced == text.replace('old a\n', 'new a\n', 1)
    appended = report.replace_section(replaced, 'c', 'new c')
    assert appended == replaced + '\n<!-- bench:c -->\nnew c\n<!-- /bench:c -->\n'


def test_a_bench_run_on_a_tiny_size_writes_its_section_with_the_conditions_of_the_measurement(tmp_path: Path):
    docs = tmp_path / 'performance.md'
    docs.write_text('# Performance\n\nbefore\n\n<!-- bench:wakeup -->\nold figures\n<!-- /bench:wakeup -->\n\nafter\n',
                    encoding='utf-8')
    result = subprocess.run([sys.executable, str(BENCH / 'bench_wakeup.py'), '--seconds', '0.05', '--busy', '0',
                             '--write-docs', str(docs)], capture_output=True, text=True, timeout=120, cwd=BENCH)
    assert result.returncode == 0, result.stderr[-2000:]
    text = docs.read_text(encoding='utf-8')
    assert text.startswith('# Performance\n\nbefore\n\n<!-- bench:wakeup -->\n') and text.endswith(
        '<!-- /bench:wakeup -->\n\nafter\n')
    section = text.split('<!-- bench:wakeup -->\n')[1].split('\n<!-- /bench:wakeup -->')[0]
    assert 'old figures' not in section
    conditions, _title, figures = section.split('\n\n')[:3]
    header, _rule, row = conditions.splitlines()
    assert header == '| command | machine | date (UTC) | load average (1 min) at start / end | software |'
    command, machine, date, load, software = (cell.strip() for cell in row.strip('|').split('|'))
    assert command == '`python bench/bench_wakeup.py --seconds 0.05 --busy 0`'
    assert machine == f'{load_report_module().cpu_model()}, {os.cpu_count()} cores'
    assert re.fullmatch(r'20\d\d-\d\d-\d\d \d\d:\d\d', date)
    assert re.fullmatch(r'\d+\.\d\d / \d+\.\d\d', load)
    assert software.startswith('Python ')
    rows = figures.splitlines()[2:]
    assert [row.split('|')[1].strip() for row in rows][:1] == ['normal scheduling']
    assert all(row.count('|') == 7 for row in rows)


def test_the_performance_document_has_well_formed_sections_each_written_by_a_script():
    text = (BENCH.parent / 'docs' / 'performance.md').read_text(encoding='utf-8')
    opened = re.findall(r'^<!-- bench:([\w-]+) -->$', text, re.MULTILINE)
    closed = re.findall(r'^<!-- /bench:([\w-]+) -->$', text, re.MULTILINE)
    assert opened == closed and len(set(opened)) == len(opened), (opened, closed)
    for name in opened:
        section = text.split(f'<!-- bench:{name} -->\n')[1].split(f'\n<!-- /bench:{name} -->')[0]
        assert section.startswith('| command | machine | date (UTC) |'), name
        scripts = set(re.findall(r'bench/(bench_\w+\.py)', section.splitlines()[2]))
        assert scripts and all((BENCH / script).is_file() for script in scripts), (name, scripts)
