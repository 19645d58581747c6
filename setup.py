"""Packaging for wallbot_sim (ament_python conventions, also pip-installable).

The same setup.py serves three install paths:

* ``colcon build`` (ROS): executables go to ``lib/wallbot_sim`` (setup.cfg) and
  config/launch/package.xml go to ``share/wallbot_sim`` via ``data_files``.
* ``pip install .``: config/*.yaml is additionally copied into the wheel as
  package data (``wallbot_sim/_data/config``) so ``wallbot_sim.paths`` finds it
  without an ament index.
* ``pip install -e .``: the package runs from the source tree and
  ``wallbot_sim.paths`` uses ``<repo>/config`` directly (no stale copies).
"""
import os
import shutil
from glob import glob

from setuptools import find_packages, setup
from setuptools.command.build_py import build_py

package_name = 'wallbot_sim'
HERE = os.path.dirname(os.path.abspath(__file__))


def _rel_glob(pattern: str) -> list:
    """Sorted glob relative to this file's directory (data_files want relative paths)."""
    return sorted(os.path.relpath(p, HERE) for p in glob(os.path.join(HERE, pattern)))


class BuildPyWithConfig(build_py):
    """build_py that also ships config/*.yaml as package data in wallbot_sim/_data/config.

    Not wallbot_sim/config: that name belongs to the wallbot_sim.config module.
    """

    def run(self):
        super().run()
        if getattr(self, 'editable_mode', False):
            return  # editable installs read <repo>/config directly
        target = os.path.join(self.build_lib, package_name, '_data', 'config')
        os.makedirs(target, exist_ok=True)
        for src in _rel_glob('config/*.yaml'):
            shutil.copy2(os.path.join(HERE, src), target)


setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(where=HERE, exclude=['test', 'test.*', 'bench', 'bench.*']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/config', _rel_glob('config/*.yaml')),
        ('share/' + package_name + '/launch', _rel_glob('launch/*.launch.py')),
    ],
    cmdclass={'build_py': BuildPyWithConfig},
    python_requires='>=3.10',
    install_requires=[
        'numpy',
        'scipy',
        'pyyaml',
        'rosbags>=0.11,<0.12',  # BagWriter writes MCAP records and chunks in rosbags' own layout
        'matplotlib',
        'numba>=0.68',  # the kernel's cache locators (wallbot_sim/model/batch/kernel/compiling.py) by their public names
        'dask[distributed]',
    ],
    extras_require={
        'ros': ['ros-jazzy-rclpy[fastrtps]', 'ros-jazzy-common-interfaces'],
        'foxglove': ['foxglove-sdk'],
        # mujoco: the independent engine the contact model is checked against (test/test_peer_mujoco.py)
        # xmlschema: the JUnit files of wallbot-sim test are validated against the JUnit schema (test/data)
        'test': ['pytest', 'pytest-xdist', 'mcap', 'colcon-common-extensions', 'import-linter', 'yourdfpy', 'foxglove-sdk',
                 'websockets', 'mujoco', 'xmlschema'],
    },
    # ignored (with a warning) by setuptools >= 72; kept for older colcon/setuptools setups
    tests_require=['pytest'],
    zip_safe=False,
    maintainer='wallbot_sim maintainers',
    maintainer_email='wallbot-sim@example.com',
    description='Simulation of a wall-climbing robot on ROS 2 Jazzy.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'wallbot-sim = wallbot_sim.cli.main:main',
            'dynamics_node = wallbot_sim.nodes.dynamics:main',
            'trajectory_node = wallbot_sim.nodes.trajectory:main',
            'constraint_config_node = wallbot_sim.nodes.constraint_config:main',
            'recorder_node = wallbot_sim.nodes.recorder:main',
            'dynamics_recorder_node = wallbot_sim.nodes.dynamics_recorder:main',
            'tracking_controller_node = wallbot_sim.nodes.controller:main',
            'cmd_vel_node = wallbot_sim.nodes.cmd_vel:main',
            'joint_bridge_node = wallbot_sim.nodes.joint_bridge:main',
            'viewer_node = wallbot_sim.nodes.viewer:main',
        ],
        # the ``wallbot`` fixture of controller tests (wallbot_sim/testing/plugin.py), in every pytest run
        # named by its module: so that ``-p wallbot_sim.testing.plugin`` and a conftest's ``pytest_plugins`` naming it
        # find it registered already, where the package is installed
        'pytest11': ['wallbot_sim.testing.plugin = wallbot_sim.testing.plugin'],
    },
)
