"""The model's coulomb contact against the same robot built independently in MuJoCo (test/peer_mujoco.py).

Both from rest, the same parameters (kinetic = static friction 0.7, no rolling resistance: MuJoCo's
friction has one coefficient and no rolling resistance). Accelerations within 0.5 %, loads within
1.5 %, the spinning robot's fall and the fast turn's yaw rate within 15 %; below the turning threshold
neither turns. docs/model.md's validation table is ``python test/peer_mujoco.py``.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import peer_mujoco
from peer_mujoco import CASES, UP, mean_acceleration, runs

ACCELERATION, LOAD, MOTION = 0.005, 0.015, 0.15


@pytest.fixture(scope='module')
def compared() -> dict[str, tuple[peer_mujoco.Trace, peer_mujoco.Trace]]:
    """Every case run once on both: (model, MuJoCo) by case name."""
    return {case.name: runs(case) for case in CASES}


def case_named(words: str) -> peer_mujoco.Case:
    (case,) = [case for case in CASES if words in case.name]
    return case


@pytest.mark.parametrize('words', ['climb below', 'climb above'])
def test_climbs_below_and_above_the_traction_limit(compared, words):
    model, peer = compared[case_named(words).name]
    assert model.ended is None
    model_ydd, peer_ydd = (mean_acceleration(trace, 0.2, 1.0)[1] for trace in (model, peer))
    assert model_ydd == pytest.approx(peer_ydd, rel=ACCELERATION)
    assert model.loads[-1] == pytest.approx(peer.loads[-1], rel=LOAD)
    if words == 'climb above':  # the wheels spin: the spin-up takes load off the front wheels
        assert model_ydd == pytest.approx((0.7 * 189.19 - 9.0 * 9.81) / 9.0, rel=1e-3)
        assert model.loads[-1, 0] < model.loads[-1, 1] - 30.0


def test_hold_facing_x(compared):
    model, peer = compared[case_named('hold facing').name]
    assert model.loads[-1] == pytest.approx(peer.loads[-1], rel=LOAD)
    assert np.max(np.abs(model.position)) < 1e-9 and np.max(np.abs(peer.position[-1] - peer.position[0])) < 1e-4


def test_spinning_wheels_facing_x_fall(compared):
    model, peer = compared[case_named('spinning wheels').name]
    assert model.ended is None
    assert model.position[-1, 1] == pytest.approx(peer.position[-1, 1], rel=MOTION)
    assert model.position[-1, 1] < -3.0


@pytest.mark.parametrize('words', ['facing up, below', 'below T*'])
def test_below_the_threshold_neither_turns(compared, words):
    model, peer = compared[case_named(words).name]
    # MuJoCo's soft contacts settle for a millisecond or two at the start: the heading, not the rate, says it
    assert np.max(np.abs(model.heading - model.heading[0])) < 1e-9
    assert np.max(np.abs(peer.heading - peer.heading[0])) < 1e-3 and abs(peer.yaw_rate[-1]) < 1e-3
    if case_named(words).theta == UP:  # it rolls down the wall as a cart with free wheels would
        assert mean_acceleration(model, 0.1, 1.0)[1] == pytest.approx(mean_acceleration(peer, 0.1, 1.0)[1],
                                                                      rel=ACCELERATION)


@pytest.mark.parametrize('words', ['facing up, above', 'above T*'])
def test_above_the_threshold_both_turn_alike(compared, words):
    case = case_named(words)
    model, peer = compared[case.name]
    assert model.yaw_rate[-1] > 5.0
    assert model.yaw_rate[-1] == pytest.approx(peer.yaw_rate[-1], rel=MOTION)
    if case.gravity > 1.0:
        assert mean_acceleration(model, 0.1, case.duration)[1] == pytest.approx(
            mean_acceleration(peer, 0.1, case.duration)[1], rel=ACCELERATION)


def test_the_peer_robot_is_the_robot_file_s():
    """The MJCF carries the robot's masses, inertias and geometry: the total mass and the CoM height."""
    import mujoco
    params = peer_mujoco.case_parameters(CASES[0])
    model = mujoco.MjModel.from_xml_string(peer_mujoco.robot_xml(params, 0.3))
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    chassis = model.body('chassis').id
    assert model.body_subtreemass[chassis] == pytest.approx(params.body_mass + 4 * params.wheel_mass)
    assert data.subtree_com[chassis] == pytest.approx([0.0, 0.0, params.com_height])
    assert math.atan2(data.xmat[chassis][3], data.xmat[chassis][0]) == pytest.approx(0.3)
