"""Install-layout checks: colcon identifies and builds wallbot_sim like a ROS package.

The colcon build runs once per module (fixture ``colcon_ws``) in a scratch
workspace holding a copy of the repository.
"""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from wallbot_sim import paths

REPO_ROOT = Path(__file__).resolve().parents[1]
COLCON = Path(sys.executable).parent / 'colcon'
EXECUTABLES = ('dynamics_node', 'trajectory_node', 'constraint_config_node',
               'recorder_node', 'dynamics_recorder_node', 'tracking_controller_node', 'cmd_vel_node', 'joint_bridge_node', 'viewer_node',
               'wallbot-sim')
IGNORED = shutil.ignore_patterns('.venv', '.git', 'build', 'install', 'log', 'runs',
                                 '__pycache__', '*.egg-info', '.pytest_cache')


def _colcon(ws: Path, *args: str, timeout: float = 600) -> subprocess.CompletedProcess:
    # --log-base keeps colcon's logs inside the scratch workspace
    cmd = [str(COLCON), '--log-base', str(ws / 'log'), *args]
    return subprocess.run(cmd, cwd=ws, capture_output=True, text=True, timeout=timeout)


def _bash(script: str, ws: Path, env: dict | None = None) -> str:
    res = subprocess.run(['bash', '-c', script], cwd=ws, capture_output=True, text=True,
                         timeout=120, env=env)
    assert res.returncode == 0, f'bash -c {script!r} failed:\n{res.stdout}\n{res.stderr}'
    return res.stdout


@pytest.fixture(scope='module')
def colcon_ws(tmp_path_factory) -> Path:
    """A colcon workspace with wallbot_sim copied into src/ and built (not symlinked)."""
    if not COLCON.exists():
        pytest.fail(f'{COLCON} missing: install the test extra (pip install -e ".[test]")')
    ws = tmp_path_factory.mktemp('colcon_ws')
    src = ws / 'src' / 'wallbot_sim'
    shutil.copytree(REPO_ROOT, src, ignore=IGNORED, symlinks=True)
    # Placeholders only in the scratch copy, for files other work may not have landed yet.
    if not (src / 'config' / 'robot.yaml').exists():
        (src / 'config').mkdir(exist_ok=True)
        (src / 'config' / 'robot.yaml').write_text('# placeholder for the packaging test\n')
    listed = _colcon(ws, 'list', '--base-paths', 'src')
    assert listed.returncode == 0, listed.stderr
    ws_list = listed.stdout
    built = _colcon(ws, 'build', '--base-paths', 'src', '--event-handlers', 'console_direct-')
    assert built.returncode == 0, f'colcon build failed:\n{built.stdout}\n{built.stderr}'
    (ws / 'colcon_list.txt').write_text(ws_list)
    return ws


def test_colcon_identifies_ament_python(colcon_ws):
    # colcon silently falls back to type "python" when catkin_pkg rejects package.xml
    fields = (colcon_ws / 'colcon_list.txt').read_text().split()
    assert fields[:1] == ['wallbot_sim'], fields
    assert fields[2:3] == ['(ros.ament_python)'], fields


def test_setup_bash_extends_ament_prefix_path(colcon_ws):
    prefix = colcon_ws / 'install' / 'wallbot_sim'
    env = {k: v for k, v in os.environ.items() if k not in ('AMENT_PREFIX_PATH',)}
    out = _bash('source install/setup.bash && printf %s "$AMENT_PREFIX_PATH"', colcon_ws, env)
    assert str(prefix) in out.split(os.pathsep), out


def test_executables_in_lib_package_dir(colcon_ws):
    lib = colcon_ws / 'install' / 'wallbot_sim' / 'lib' / 'wallbot_sim'
    for exe in EXECUTABLES:
        path = lib / exe
        assert path.is_file(), f'{path} missing; lib has {sorted(os.listdir(lib)) if lib.is_dir() else None}'
        assert os.access(path, os.X_OK), path


def test_share_layout(colcon_ws):
    prefix = colcon_ws / 'install' / 'wallbot_sim'
    for rel in ('share/ament_index/resource_index/packages/wallbot_sim',
                'share/wallbot_sim/package.xml',
                'share/wallbot_sim/config/robot.yaml',
                'share/wallbot_sim/launch/wallbot.launch.py'):
        assert (prefix / rel).is_file(), rel


def _installed_config_dir(ws: Path, source_setup: bool) -> Path:
    """config_dir() as seen by the colcon-installed copy of wallbot_sim."""
    prefix = ws / 'install' / 'wallbot_sim'
    site = next(prefix.glob('lib/python3*/site-packages'))
    env = {k: v for k, v in os.environ.items()
           if k not in ('AMENT_PREFIX_PATH', 'PYTHONPATH', 'WALLBOT_SIM_CONFIG_DIR')}
    probe = (f'{sys.executable} -c "from wallbot_sim import paths; print(paths.config_dir())"')
    if source_setup:
        script = f'source install/setup.bash && {probe}'
    else:
        script = f'PYTHONPATH={site} {probe}'
    out = _bash(script, ws, env).strip().splitlines()[-1]
    return Path(out)


def test_installed_copy_finds_config_in_ament_share(colcon_ws):
    found = _installed_config_dir(colcon_ws, source_setup=True)
    assert found == colcon_ws / 'install' / 'wallbot_sim' / 'share' / 'wallbot_sim' / 'config'
    assert (found / 'robot.yaml').is_file()


def test_installed_copy_without_ament_uses_package_data(colcon_ws):
    # same layout as a plain `pip install .`: config shipped inside the package
    found = _installed_config_dir(colcon_ws, source_setup=False)
    assert found.parts[-4:] == ('site-packages', 'wallbot_sim', '_data', 'config'), found
    assert (found / 'robot.yaml').is_file()


def test_config_dir_finds_robot_yaml():
    cfg = paths.config_dir()
    assert (cfg / 'robot.yaml').is_file()
    assert paths.robot_yaml() == cfg / 'robot.yaml'
    assert paths.robot_yaml().is_file()


def test_scenario_yaml_lookup():
    cfg = paths.config_dir()
    scenarios = sorted(p.stem for p in cfg.glob('*.yaml') if p.stem != 'robot')
    for name in scenarios:
        assert paths.scenario_yaml(name) == cfg / f'{name}.yaml'
    with pytest.raises(FileNotFoundError):
        paths.scenario_yaml('no_such_scenario')


def test_config_dir_env_override(tmp_path, monkeypatch):
    (tmp_path / 'robot.yaml').write_text('{}\n')
    monkeypatch.setenv(paths.ENV_OVERRIDE, str(tmp_path))
    assert paths.config_dir() == tmp_path
