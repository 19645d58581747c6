"""The robot built independently in MuJoCo, and the cases test_peer_mujoco.py compares with the model.

``python test/peer_mujoco.py`` prints the side-by-side table of docs/model.md's validation section.

The MuJoCo robot: a chassis on a free joint over the wall plane (z = 0, normal +Z, gravity along -Y),
four wheel bodies on hinges about the chassis' y axis, each touching the wall with one sphere of the
wheel radius: one contact per wheel with an isotropic Coulomb friction cone (condim 3, elliptic cones).
The belt is a joint equality (front spin = rear spin), the adhesion force an applied force along -Z
through the chassis' centre of mass (on the line through the geometric centre, as in the model), the
motor torques actuators on the wheel hinges, half a side's torque on each wheel. Masses and inertias
are the robot file's; the chassis' CoM sits at the height that puts the whole robot's at com_height.

MuJoCo's contacts are soft: a contact force needs a little penetration and a sticking contact creeps.
The settings that make them hard enough for the comparison (``SETTINGS``): 0.2 ms steps, contact and
equality time constants of 2 ms (solref 0.002 1, ten steps), impratio 10 (friction stiffer than the
normal direction), and the noslip solver (20 iterations), which removes the creep of sticking contacts.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from wallbot_sim.model import ConstraintSelection, Robot, RobotParameters, Simulation
from wallbot_sim.model.contact import DetachedError

SETTINGS = dict(timestep=0.0001, contact_solref='0.002 1', friction_solref='0.002 1', contact_solimp='0 0.95 0.00003 0.5 2',
                belt_solref='0.002 1', noslip_iterations=20, cone='elliptic')
PEER_PARAMETERS = dict(kinetic_friction=0.7, rolling_resistance=0.0)
"""MuJoCo's friction has one coefficient and no rolling resistance: the model is compared with the same."""
DRIVEN = ConstraintSelection(trajectory=False, belt=True, non_lateral=True, nonslip=True)


def robot_xml(params: RobotParameters, theta: float) -> str:
    """The MJCF of the robot at rest at the origin, heading ``theta``."""
    a, b, r = params.half_wheelbase, params.half_track, params.wheel_radius
    total = params.body_mass + 4 * params.wheel_mass
    body_height = (total * params.com_height - 4 * params.wheel_mass * r) / params.body_mass
    wheels = ''.join(f'''
      <body name="wheel{i + 1}" pos="{x} {y} {r}">
        <joint name="spin{i + 1}" type="hinge" axis="0 1 0" damping="0" armature="0"/>
        <inertial pos="0 0 0" mass="{params.wheel_mass}"
                  diaginertia="{params.wheel_yaw_inertia} {params.wheel_spin_inertia} {params.wheel_yaw_inertia}"/>
        <geom name="tyre{i + 1}" type="sphere" size="{r}" contype="0" conaffinity="0"/>
      </body>''' for i, (x, y) in enumerate(((a, b), (-a, b), (a, -b), (-a, -b))))
    belts = ''.join(f'<joint joint1="spin{front}" joint2="spin{rear}" polycoef="0 1 0 0 0" solref="{SETTINGS["belt_solref"]}"/>'
                    for front, rear in ((1, 2), (3, 4)))
    contacts = ''.join(f'''<pair geom1="wall" geom2="tyre{i}" condim="3" friction="{mu} {mu} 0 0 0"
          solref="{SETTINGS['contact_solref']}" solreffriction="{SETTINGS['friction_solref']}"
          solimp="{SETTINGS['contact_solimp']}"/>'''
                       for i in range(1, 5) for mu in (params.wall_friction,))
    motors = ''.join(f'<motor joint="spin{i}" gear="1"/>' for i in range(1, 5))
    return f'''<mujoco model="wallbot">
  <option timestep="{SETTINGS['timestep']}" gravity="0 {-params.gravity} 0" cone="{SETTINGS['cone']}"
          noslip_iterations="{SETTINGS['noslip_iterations']}"/>
  <worldbody>
    <geom name="wall" type="plane" size="0 0 1" contype="0" conaffinity="0"/>
    <body name="chassis" pos="0 0 0" quat="{math.cos(theta / 2)} 0 0 {math.sin(theta / 2)}">
      <freejoint name="chassis"/>
      <inertial pos="0 0 {body_height}" mass="{params.body_mass}"
                diaginertia="{params.body_yaw_inertia} {params.body_yaw_inertia} {params.body_yaw_inertia}"/>{wheels}
    </body>
  </worldbody>
  <contact>{contacts}</contact>
  <equality>{belts}</equality>
  <actuator>{motors}</actuator>
</mujoco>'''


class Trace(NamedTuple):
    """A run sampled every millisecond: t, centre (x, y), heading, velocity (vx, vy), yaw rate, wheel loads."""

    t: np.ndarray
    position: np.ndarray
    heading: np.ndarray
    velocity: np.ndarray
    yaw_rate: np.ndarray
    loads: np.ndarray
    ended: float | None
    """The time the model's run ended at a lift-off (None: it ran to the end)."""


def mujoco_run(params: RobotParameters, theta: float, torque: tuple[float, float], duration: float) -> Trace:
    """The MuJoCo robot from rest, under side torques ``torque``, sampled every millisecond."""
    import mujoco
    model = mujoco.MjModel.from_xml_string(robot_xml(params, theta))
    data = mujoco.MjData(model)
    chassis = model.body('chassis').id
    tyres = [model.geom(f'tyre{i}').id for i in range(1, 5)]
    data.ctrl[:] = [torque[0] / 2, torque[0] / 2, torque[1] / 2, torque[1] / 2]
    adhesion = Robot(params).adsorption.applied_force
    per_sample = round(1e-3 / model.opt.timestep)
    samples = round(duration / 1e-3) + 1
    rows = {name: [] for name in Trace._fields[:-1]}
    force = np.zeros(6)
    mujoco.mj_forward(model, data)
    for sample in range(samples):
        loads = np.zeros(4)
        for _ in range(per_sample if sample else 1):
            if sample:
                data.xfrc_applied[chassis, 2] = -adhesion
                mujoco.mj_step(model, data)
            for k in range(data.ncon):
                contact = data.contact[k]
                for wheel, tyre in enumerate(tyres):
                    if tyre in (contact.geom1, contact.geom2):
                        mujoco.mj_contactForce(model, data, k, force)
                        loads[wheel] += force[0] / (per_sample if sample else 1)
        rotation = data.xmat[chassis].reshape(3, 3)
        rows['t'].append(data.time)
        rows['position'].append(data.qpos[:2].copy())
        rows['heading'].append(math.atan2(rotation[1, 0], rotation[0, 0]))
        rows['velocity'].append(data.qvel[:2].copy())
        rows['yaw_rate'].append((rotation @ data.qvel[3:6])[2])  # a free joint's angular velocity is in its body's axes
        rows['loads'].append(loads)
    return Trace(*(np.array(values) for values in rows.values()), None)


def model_run(params: RobotParameters, theta: float, torque: tuple[float, float], duration: float) -> Trace:
    """The model (coulomb contact, belt + non-lateral + nonslip) from rest, every step."""
    simulation = Simulation(Robot(params), None, DRIVEN, np.array([0.0, 0.0, theta, 0, 0, 0, 0]), np.zeros(7),
                            contact='coulomb')
    simulation.set_motor_torque(*torque)
    outputs = []
    ended = None
    try:
        simulation.run(duration, outputs.append)
    except DetachedError as detached:
        ended = detached.t
    return Trace(np.array([o.t for o in outputs]), np.array([o.q[:2] for o in outputs]),
                 np.array([o.q[2] for o in outputs]), np.array([o.qd[:2] for o in outputs]),
                 np.array([o.qd[2] for o in outputs]), np.array([o.contact.loads for o in outputs]), ended)


class Case(NamedTuple):
    name: str
    theta: float
    torque: tuple[float, float]
    duration: float
    gravity: float = 9.81
    adhesion_force: float | None = None
    """None: the robot file's rule, k_ad F_min."""


UP = math.pi / 2
CASES = (
    Case('climb below the traction limit (facing up, 2 N m per side)', UP, (2.0, 2.0), 1.0),
    Case('climb above it, wheels spinning (facing up, 3 N m)', UP, (3.0, 3.0), 1.0),
    Case('hold facing +X (no torque)', 0.0, (0.0, 0.0), 0.5),
    Case('spinning wheels facing +X (3 N m)', 0.0, (3.0, 3.0), 1.0),
    Case('turn in place facing up, below the threshold (-1 / +1 N m)', UP, (-1.0, 1.0), 1.0),
    Case('turn in place facing up, above it (-3 / +3 N m)', UP, (-3.0, 3.0), 0.5),
    Case('turn in place, gravity 0.01, F_ad 189.19 N, below T* (-1.54 / +1.54 N m)', 0.0, (-1.54, 1.54), 1.0, 0.01,
         189.19),
    Case('turn in place, gravity 0.01, F_ad 189.19 N, above T* (-1.85 / +1.85 N m)', 0.0, (-1.85, 1.85), 1.0, 0.01,
         189.19),
)


def case_parameters(case: Case) -> RobotParameters:
    return RobotParameters(**PEER_PARAMETERS, gravity=case.gravity, adhesion_force=case.adhesion_force)


def runs(case: Case) -> tuple[Trace, Trace]:
    """(model, MuJoCo) of the case."""
    params = case_parameters(case)
    return (model_run(params, case.theta, case.torque, case.duration),
            mujoco_run(params, case.theta, case.torque, case.duration))


def mean_acceleration(trace: Trace, start: float, end: float) -> np.ndarray:
    """(xdd, ydd) averaged over [start, end] from the velocities."""
    first, last = (int(np.argmin(np.abs(trace.t - moment))) for moment in (start, end))
    return (trace.velocity[last] - trace.velocity[first]) / (trace.t[last] - trace.t[first])


def table() -> str:
    """The comparison as docs/model.md shows it (markdown)."""
    lines = ['| case | quantity | model | MuJoCo | difference |', '|---|---|---|---|---|']

    def row(case: Case, quantity: str, model: float, peer: float, digits: int = 4) -> None:
        difference = f'{abs(model - peer) / abs(peer) * 100:.2f} %' if abs(peer) > 1e-3 else f'{model - peer:.2g}'
        lines.append(f'| {case.name} | {quantity} | {model:.{digits}f} | {peer:.{digits}f} | {difference} |')

    for case in CASES:
        model, peer = runs(case)
        if case.torque == (0.0, 0.0):
            for wheel in (0, 2):
                row(case, f'N{wheel + 1} at {case.duration:g} s (N)', model.loads[-1, wheel], peer.loads[-1, wheel], 2)
            row(case, f'y at {case.duration:g} s (m)', model.position[-1, 1], peer.position[-1, 1], 6)
        elif case.torque[0] == case.torque[1] and case.theta == UP:
            row(case, 'ydd over 0.2-1 s (m/s^2)', mean_acceleration(model, 0.2, 1.0)[1],
                mean_acceleration(peer, 0.2, 1.0)[1])
            for wheel in (0, 1):
                row(case, f'N{wheel + 1} at 1 s (N)', model.loads[-1, wheel], peer.loads[-1, wheel], 2)
        elif case.torque[0] == case.torque[1]:
            row(case, f'y at {case.duration:g} s (m)', model.position[-1, 1], peer.position[-1, 1], 3)
        else:
            row(case, f'yaw rate at {case.duration:g} s (rad/s)', model.yaw_rate[-1], peer.yaw_rate[-1], 4)
            if case.gravity > 1.0:
                row(case, f'ydd over 0.1-{case.duration:g} s (m/s^2)', mean_acceleration(model, 0.1, case.duration)[1],
                    mean_acceleration(peer, 0.1, case.duration)[1])
    return '\n'.join(lines)


if __name__ == '__main__':
    import mujoco
    print(f'MuJoCo {mujoco.__version__}, {", ".join(f"{k} {v}" for k, v in SETTINGS.items())}')
    print(table())
