"""The layering is a checked contract (import-linter, contracts in setup.cfg), not a convention."""

from __future__ import annotations

import ast
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO_ROOT = Path(__file__).resolve().parents[1]
LINT_IMPORTS = Path(sys.executable).parent / 'lint-imports'


def lint_imports(root: Path, python_path: Path | None = None) -> subprocess.CompletedProcess:
    env = dict(os.environ)
    if python_path is not None:
        env['PYTHONPATH'] = str(python_path)
    return subprocess.run([str(LINT_IMPORTS), '--config', str(root / 'setup.cfg'), '--no-cache'], cwd=root,
                          capture_output=True, text=True, timeout=300, env=env)


@pytest.fixture(scope='module')
def linter() -> Path:
    if not LINT_IMPORTS.exists():
        pytest.fail(f'{LINT_IMPORTS} is missing: install the test extra (pip install -e ".[test]")')
    return LINT_IMPORTS


def test_every_layering_contract_is_kept(linter):
    result = lint_imports(REPO_ROOT)
    assert result.returncode == 0, result.stdout + result.stderr
    assert 'Contracts: 7 kept, 0 broken.' in result.stdout


@pytest.mark.parametrize('module, line, contract', [
    ('wallbot_msgs_py/topics.py', 'import wallbot_sim.model', 'wallbot_msgs_py is the interface contract only'),
    ('wallbot_sim/cli/compare.py', 'from wallbot_sim.cli import plot', 'never imports another verb'),
    ('wallbot_sim/model/robot.py', 'import rclpy', 'wallbot_sim.model is pure NumPy'),
    ('wallbot_sim/model/constraint_set.py', 'from wallbot_msgs_py import topics', 'wallbot_sim.model is pure NumPy'),
    ('wallbot_sim/rundata/load.py', 'from wallbot_sim.cli.errors import CliError', 'know nothing of the command line'),
    ('wallbot_sim/loop/blocks.py', 'import rclpy',
     'the dynamics loop (its package), its settings, sensors'),
    ('wallbot_sim/settings/table.py', 'import rcl_interfaces',
     'the dynamics loop (its package), its settings, sensors'),
    ('wallbot_sim/urdf.py', 'import std_msgs', 'the URDF generator knows no ROS'),
    ('wallbot_sim/view.py', 'import visualization_msgs', 'what the viewer draws and encodes'),
], ids=['interface', 'verbs', 'model', 'model-interface', 'libraries', 'loop', 'settings', 'urdf', 'view'])
def test_a_broken_contract_fails(linter, tmp_path, module, line, contract):
    """The same check on a copy with one forbidden import added fails, naming the contract."""
    for package in ('wallbot_sim', 'wallbot_msgs_py'):
        shutil.copytree(REPO_ROOT / package, tmp_path / package, ignore=shutil.ignore_patterns('__pycache__'))
    shutil.copy(REPO_ROOT / 'setup.cfg', tmp_path / 'setup.cfg')
    target = tmp_path / module
    target.write_text(target.read_text() + f'\n{line}  # noqa\n')
    result = lint_imports(tmp_path, python_path=tmp_path)
    assert result.returncode != 0
    broken = result.stdout[result.stdout.index('Broken contracts'):]
    assert contract in broken.replace('\n', ' ')


def imported_test_modules(source: str) -> list[str]:
    """The test modules (``test_*``) that Python ``source`` imports."""
    names = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            names += [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names.append(node.module)
    return [name for name in names if name.split('.')[0].startswith('test_')]


def test_no_test_module_imports_another():
    """Shared helpers live in helper modules (graph_helpers, cli_helpers, ...), never in a test module:
    importing one would run its module-level code and tie the two files' tests together."""
    files = sorted([*(REPO_ROOT / 'test').glob('*.py'), *(REPO_ROOT / 'bench').glob('*.py')])
    assert len(files) > 30
    offenders = {path.name: imported_test_modules(path.read_text()) for path in files}
    assert {name: imported for name, imported in offenders.items() if imported} == {}


def test_the_test_import_check_finds_them():
    source = ('import os, test_pacing\nfrom test_nodes_graph import Graph\n'
              'from graph_helpers import ns\nfrom . import x\n')
    assert imported_test_modules(source) == ['test_pacing', 'test_nodes_graph']
