"""The contact part of a step's outputs (``ContactOutputs``): ideal contact's from the solved motion, coulomb
contact's from a settled boundary (docs/model.md 11)."""

from __future__ import annotations

from typing import Sequence

import numpy as np

from wallbot_sim.model.contact import ContactSolution, coulomb_table
from wallbot_sim.model.contact_kinematics import contact_velocities
from wallbot_sim.model.friction import FrictionUse, channel_loads, friction_use
from wallbot_sim.model.normal_loads import normal_loads
from wallbot_sim.model.outputs import ContactOutputs, DriveForces, drive_forces
from wallbot_sim.model.robot import Robot
from wallbot_sim.model.solver import ConstrainedMotion
from wallbot_sim.model.wheel_forces import WheelOutputs, ideal_wheel_outputs


def ideal_measures(robot: Robot, q: np.ndarray, qd: np.ndarray,
                   motion: ConstrainedMotion) -> tuple[np.ndarray, FrictionUse, DriveForces, WheelOutputs]:
    """Normal loads (11.1), channel friction use, the drive forces they come from and each wheel's share of the
    chassis wrench (one row), of an ideal motion at (q, qd)."""
    loads = normal_loads(robot, q, qd, motion.acceleration)
    drive = drive_forces(q[2], motion.constraint_force[:3], robot.params.half_track)
    use = friction_use((drive.left, drive.right, drive.lateral), loads, robot.wall_load, robot.params.wall_friction)
    wheels = ideal_wheel_outputs(robot, q[None], qd[None], motion.constraint_force[None, :3], loads[None])
    return loads, use, drive, wheels


def ideal_contact(robot: Robot, loads: np.ndarray, use: FrictionUse, wheels: WheelOutputs) -> ContactOutputs:
    """Ideal contact's outputs: nothing slides; each wheel's share of the chassis wrench (``wheels``, one row)."""
    static = robot.params.wall_friction
    limits = tuple(static * load for load in channel_loads(loads, robot.wall_load))
    return ContactOutputs(loads, use, limits, (False, False, False), None, wheels.forces[0],  # type: ignore[arg-type]
                          wheels.use[0], (False, False, False, False), wheels.velocities[0])


def coulomb_contact(robot: Robot, directions: Sequence[int], q: np.ndarray, qd: np.ndarray,
                    solution: ContactSolution) -> tuple[DriveForces, ContactOutputs]:
    """Coulomb contact's drive forces and outputs at a settled boundary (``coulomb_table``: the channels as sums
    of the wheels' forces, each wheel's use against its own mu_s); ``directions``: the contact layout's."""
    sliding = tuple(wheel in solution.sliding for wheel in range(4))
    table = coulomb_table(solution.loads[None], solution.wheel_forces[None], np.array([sliding]), directions,
                          robot.params.wall_friction, robot.wall_load, robot.wheel_friction(q)[0][None])
    return DriveForces(*table.drive[0].tolist()), ContactOutputs(
        solution.loads, FrictionUse(*table.use[0].tolist()), tuple(table.limits[0].tolist()),  # type: ignore
        tuple(table.slipping[0].tolist()), solution.friction_force, solution.wheel_forces,  # type: ignore
        table.wheel_use[0], sliding,  # type: ignore[arg-type]
        contact_velocities(q[None, 2], qd[None], robot.wheel_offsets, robot.params.wheel_radius)[0])
