"""Normal loads of the four wheels (docs/model.md 11.1).

The adhesion force F_ad presses the robot to the wall at the geometric centre; the wall pushes
back at the wheels with N_1..N_4. Gravity and inertia act on the whole mass m_t at the CoM
height h, so the loads also balance their moment about the wall plane:

    sum N_i = F_ad + W,  sum x_i N_i = h F_bx + W c_Gx,  sum y_i N_i = h F_by + W c_Gy,

with F_b = R(th)^T m_t (g_vec - a_G) in the body frame, g_vec = (0, -g sin i) the in-plane part of
gravity, W = m_t g cos i its out-of-plane part pressing the robot on the surface at its CoM c_G =
m_b c / m_t (docs/model.md 13.1). Four loads, three equations: the
least-norm solution (a rigid chassis on four equal springs), in closed form for the rectangle.
"""

from __future__ import annotations

import math

import numpy as np

from wallbot_sim.model.robot import Robot


def normal_loads(robot: Robot, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray, spin_momentum: bool = False) -> np.ndarray:
    """N_i = (F_ad + W)/4 + h F_bx x_i/(4 a^2) + h F_by y_i/(4 b^2), wheels in order 1..4 (N).

    ``spin_momentum`` (coulomb contact, docs/model.md 11.1): the moment balance also turns the wheels'
    spin angular momentum J_w pd_i along y_p, whose rate J_w (sum pdd_i y_p - thd sum pd_i x_p) takes
    J_w sum pdd_i from h F_bx and J_w thd sum pd_i from h F_by.
    """
    params = robot.params
    theta, thd, thdd = float(q[2]), float(qd[2]), float(qdd[2])
    cos_t, sin_t = math.cos(theta), math.sin(theta)
    sx, sy = robot.first_moment.tolist()
    # m_t a_G = m_t (xdd, ydd) + thdd R S s - thd^2 R s
    rsx, rsy = cos_t * sx - sin_t * sy, sin_t * sx + cos_t * sy
    mass = robot.total_mass
    inertial_x = mass * float(qdd[0]) - thdd * rsy - thd * thd * rsx
    inertial_y = mass * float(qdd[1]) + thdd * rsx - thd * thd * rsy
    fx, fy = -inertial_x, -mass * robot.slope_gravity - inertial_y  # F_gi = m_t (g_vec - a_G), wall frame
    body_x, body_y = cos_t * fx + sin_t * fy, -sin_t * fx + cos_t * fy
    a, b, h = params.half_wheelbase, params.half_track, params.com_height
    # the weight's out-of-plane part m_t g cos i acts at the whole robot's CoM, m_b c / m_t from the centre
    moment_x = h * body_x + robot.normal_weight * sx / mass
    moment_y = h * body_y + robot.normal_weight * sy / mass
    if spin_momentum:
        spin = params.wheel_spin_inertia
        moment_x -= spin * float(qdd[3] + qdd[4] + qdd[5] + qdd[6])
        moment_y -= spin * thd * float(qd[3] + qd[4] + qd[5] + qd[6])
    offsets = robot.wheel_offsets
    return (0.25 * robot.wall_load + (0.25 * moment_x / (a * a)) * offsets[:, 0]
            + (0.25 * moment_y / (b * b)) * offsets[:, 1])


def load_acceleration_gain(robot: Robot, q: np.ndarray, spin_momentum: bool = False) -> np.ndarray:
    """L (4 x 7): how the loads follow the acceleration, N(qdd) = N(0) + L qdd at the same (q, qd).

    The loads move through the two body-frame moments of ``normal_loads``: h F_b, with
    m_t a_G = (m_t xdd - thdd (R S s)_y, m_t ydd + thdd (R S s)_x) + terms in thd, and with
    ``spin_momentum`` the wheels' J_w sum pdd_i.
    """
    params = robot.params
    theta = float(q[2])
    cos_t, sin_t = math.cos(theta), math.sin(theta)
    sx, sy = robot.first_moment.tolist()
    rsx, rsy = cos_t * sx - sin_t * sy, sin_t * sx + cos_t * sy
    mass, h = robot.total_mass, params.com_height
    moments = np.zeros((2, 7))
    moments[:, :3] = h * np.array([[-cos_t * mass, -sin_t * mass, cos_t * rsy - sin_t * rsx],
                                   [sin_t * mass, -cos_t * mass, -sin_t * rsy - cos_t * rsx]])
    if spin_momentum:
        moments[0, 3:] = -params.wheel_spin_inertia
    a, b = params.half_wheelbase, params.half_track
    return (robot.wheel_offsets * (0.25 / (a * a), 0.25 / (b * b))) @ moments
