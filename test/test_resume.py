"""Resume after a restart, without DDS: the snapshot codec, the keeper, the start-up gate, and a
simulation restored from a snapshot continuing bit for bit. (Over DDS: test_faults.py.)"""

from __future__ import annotations

import math

import numpy as np
import pytest

from wallbot_msgs_py import bagio, topics
from wallbot_msgs_py.snapshot import (
    LENGTH, LENGTH_V1, ContactState, DynamicsSnapshot, SnapshotKeeper, decode_snapshot, encode_snapshot)
from wallbot_sim.config import load_robot_parameters, load_scenario
from wallbot_sim.model import ConstraintSelection, ParameterError, Robot, Simulation
from wallbot_sim.model.batch import kernel
from wallbot_sim.model.contact import CoulombState
from wallbot_sim.model.simulation import NUMBA, PYTHON
from wallbot_sim.loop.resume import KEEPER_ANSWER, ResumeGate

MS = 1_000_000


def snapshot(steps: int = 1234, seen_until_ns: int | None = None, **changes) -> DynamicsSnapshot:
    values = dict(anchor=0.25, steps=steps, dt=1e-3, q=tuple(0.1 * i for i in range(7)),
                  qd=tuple(-0.01 * i for i in range(7)), motor_torque=(0.5, -0.25), command=(0.5, -0.25),
                  command_since=1.2, command_expired=False, switches=(True, True, False, True, True),
                  gains=(5.0, 6.0), paused=False, seen_until_ns=0)
    values.update(changes)
    kept = DynamicsSnapshot(**values)
    return DynamicsSnapshot(**{**values, 'seen_until_ns': kept.stamp_ns if seen_until_ns is None else seen_until_ns})


def test_snapshot_values_round_trip_exactly():
    kept = snapshot(q=(0.8, 1e-17, 7.123456789012345, -3.0, 2.5, math.pi, -math.e))
    values = kept.to_values()
    assert len(values) == LENGTH
    assert DynamicsSnapshot.from_values(values) == kept
    assert kept.t == 0.25 + 1234 * 1e-3 and kept.stamp_ns == 1_484 * MS
    without_command = snapshot(command=None)
    assert DynamicsSnapshot.from_values(without_command.to_values()).command is None
    assert kept.contact is None and values[33:] == [0.0] * (LENGTH - 33)
    contact = ContactState(sliding=(True, False, False, True), loads=(61.25, 0.5, 1e-17, 80.0),
                           friction=(-3.5, 0.25, 0.0, 0.0, 0.0, 0.0, 1.0 / 3.0, -math.pi))
    sliding = snapshot(contact=contact)
    assert DynamicsSnapshot.from_values(sliding.to_values()) == sliding
    assert sliding.to_values()[33:38] == [1.0, 1.0, 0.0, 0.0, 1.0]


def test_a_v1_snapshot_is_read_without_a_contact_state():
    """The first layout (33 values under its own label), as a keeper of an older build holds it."""
    kept = snapshot(contact=ContactState((True,) * 4, (1.0,) * 4, (0.5,) * 8))
    v1 = bagio.deserialize(encode_snapshot(kept), topics.STATE_SNAPSHOT.type)
    v1.layout.dim[0].label, v1.data = 'wallbot_dynamics_snapshot_v1', v1.data[:LENGTH_V1]
    assert decode_snapshot(bagio.serialize(v1, topics.STATE_SNAPSHOT.type)) == snapshot()
    v1.data = np.array(kept.to_values())
    with pytest.raises(ValueError, match=r'\(wallbot_dynamics_snapshot_v1\) has 33 values, got 50'):
        decode_snapshot(bagio.serialize(v1, topics.STATE_SNAPSHOT.type))


@pytest.mark.parametrize('edit, reason', [
    (lambda v: v[:-1], r'has 50 values \(33 in v1\), got 49'),
    (lambda v: v[:35] + [0.5] + v[36:], 'neither 0 nor 1'),
    (lambda v: v[:5] + [math.nan] + v[6:], 'not finite'),
    (lambda v: v[:1] + [2.5] + v[2:], 'whole numbers'),
    (lambda v: v[:2] + [0.0] + v[3:], 'dt must be > 0'),
    (lambda v: v[:31] + [0.5] + v[32:], 'neither 0 nor 1'),
])
def test_malformed_snapshots_are_refused_with_the_reason(edit, reason):
    with pytest.raises(ValueError, match=reason):
        DynamicsSnapshot.from_values(edit(snapshot().to_values()))


def test_snapshot_message_carries_the_label_and_an_empty_one_means_nothing_held():
    """The bytes are what rosbags serializes for the Float64MultiArray they hold; the label tells a snapshot."""
    kept = snapshot()
    data = encode_snapshot(kept)
    msg = bagio.deserialize(data, topics.STATE_SNAPSHOT.type)
    assert [dim.label for dim in msg.layout.dim] == ['wallbot_dynamics_snapshot_v2']
    assert list(msg.data) == kept.to_values() and bagio.serialize(msg, topics.STATE_SNAPSHOT.type) == data
    assert decode_snapshot(data) == kept
    assert decode_snapshot(encode_snapshot(None)) is None
    msg.layout.dim[0].label = 'something else'
    with pytest.raises(ValueError, match='not a dynamics snapshot'):
        decode_snapshot(bagio.serialize(msg, topics.STATE_SNAPSHOT.type))
    msg.layout.dim[0].label, msg.data = 'wallbot_dynamics_snapshot_v2', msg.data[:5]
    with pytest.raises(ValueError, match='has 50 values, got 5'):
        decode_snapshot(bagio.serialize(msg, topics.STATE_SNAPSHOT.type))


def test_keeper_announces_nothing_then_holds_the_newest_snapshot_seen_until_the_newest_stamp():
    keeper = SnapshotKeeper()
    assert decode_snapshot(keeper.due()) is None and keeper.due() is None  # "nothing held", announced once
    keeper.snapshot(snapshot(steps=10))  # t = 0.26 s
    assert decode_snapshot(keeper.due()).seen_until_ns == 260 * MS  # no step message yet: its own
    for stamp in (261, 262, 263):
        keeper.stamp('/wallbot/odom', stamp * MS)
    keeper.stamp('/wallbot/wheel_states', 262 * MS)  # another stream, one message behind
    held = decode_snapshot(keeper.due())
    assert held.seen_until_ns == 263 * MS and held.steps == 10, 'the snapshot, seen until the newest stamp'
    assert keeper.due() is None, 'unchanged: nothing to republish'
    # a reset: every stream goes back to 0 and the dynamics sends a snapshot at t = 0
    keeper.snapshot(snapshot(steps=0, anchor=0.0))
    keeper.stamp('/wallbot/odom', 0)
    keeper.stamp('/wallbot/wheel_states', 0)
    held = decode_snapshot(keeper.due())
    assert (held.t, held.seen_until_ns) == (0.0, 0)


def test_keeper_holds_no_snapshot_past_what_it_received_while_an_older_one_serves():
    """A loaded keeper gets snapshots ahead of the step messages: it republishes the newest one it has
    seen the steps up to (the resumed dynamics recomputes from there), never one that would skip steps."""
    keeper = SnapshotKeeper()
    keeper.snapshot(snapshot(steps=10))  # t = 0.26 s
    keeper.stamp('/wallbot/odom', 262 * MS)
    keeper.snapshot(snapshot(steps=20))  # t = 0.27 s, before its steps arrived
    keeper.snapshot(snapshot(steps=30))  # t = 0.28 s
    held = decode_snapshot(keeper.due())
    assert (held.steps, held.seen_until_ns) == (10, 262 * MS)
    keeper.stamp('/wallbot/odom', 275 * MS)
    held = decode_snapshot(keeper.due())
    assert (held.steps, held.seen_until_ns) == (20, 275 * MS)
    keeper.stamp('/wallbot/odom', 281 * MS)
    assert decode_snapshot(keeper.due()).steps == 30
    keeper.snapshot(snapshot(steps=0, anchor=0.0))  # a reset: the older run's snapshots are no longer its
    keeper.stamp('/wallbot/odom', 0)
    assert decode_snapshot(keeper.due()).t == 0.0


def test_gate_waits_for_a_keeper_from_its_first_question_until_a_deadline():
    gate = ResumeGate(wait=1.0)
    assert not gate.settle(100.0, keeper_seen=False)  # the wait starts here (after wait_for_recorder, say)
    assert not gate.settle(100.9, keeper_seen=False)
    assert gate.settle(101.0, keeper_seen=False) and 'no keeper' in gate.timed_out and gate.snapshot is None
    gate.offer(snapshot())  # too late: the node started fresh
    assert gate.snapshot is None

    slow = ResumeGate(wait=1.0)
    assert not slow.settle(100.0, keeper_seen=False)
    assert not slow.settle(100.8, keeper_seen=True)  # a keeper discovered: its message is on the way
    assert not slow.settle(101.5, keeper_seen=True)
    kept = snapshot()
    slow.offer(kept)
    assert slow.settle(101.6, keeper_seen=True) and slow.snapshot == kept and slow.timed_out is None

    mute = ResumeGate(wait=1.0)
    mute.settle(100.0, keeper_seen=True)
    assert not mute.settle(100.0 + KEEPER_ANSWER - 0.01, keeper_seen=True)
    assert mute.settle(100.0 + KEEPER_ANSWER, keeper_seen=True) and 'sent nothing' in mute.timed_out

    answered = ResumeGate(wait=1.0)
    answered.offer(None)  # a keeper that holds nothing: start fresh at once
    assert answered.settle(0.0, keeper_seen=True) and answered.timed_out is None and answered.snapshot is None

    first = ResumeGate(wait=1.0)
    first.offer(kept)
    first.offer(None)  # the first answer decides
    assert first.settle(0.0, keeper_seen=True) and first.snapshot == kept
    assert ResumeGate(wait=0.0).settle(0.0, keeper_seen=True), 'resume_wait 0: never waits'


def test_catch_up_publishes_from_the_first_stamp_the_graph_has_not_seen():
    gate = ResumeGate(wait=1.0)
    assert gate.publishes(5 * MS) and not gate.catching_up
    gate.catch_up_to(263 * MS)
    assert [gate.publishes(s * MS) for s in (261, 262, 263)] == [False, False, False]
    assert gate.publishes(264 * MS) and not gate.catching_up
    assert gate.publishes(265 * MS)
    gate.catch_up_to(10 * MS)
    gate.stop_catch_up()
    assert gate.publishes(0)


def settled_states(sim: Simulation, until: int) -> list[np.ndarray]:
    """Each state and its solve after a step, as the node takes them, up to step ``until``."""
    out = []
    while sim.steps < until:
        sim.step()
        result = sim.outputs()  # as the node does after every step
        out.append(np.concatenate(([result.t], result.q, result.qd, result.constraint_force, result.contact.loads)))
    return out


def test_a_simulation_restored_from_a_snapshot_continues_bit_for_bit():
    robot = Robot(load_robot_parameters())
    scenario = load_scenario('circle')
    q0, qd0 = scenario.initial_state(robot)
    selection = ConstraintSelection.parse('belt,non_lateral,nonslip')

    def simulation(t0: float) -> Simulation:
        sim = Simulation(robot, scenario.reference, selection, q0, qd0, t0=t0)
        sim.set_motor_torque(0.0, 0.0)
        return sim

    t0 = 0.3  # a run segment that does not start at 0 (a rate change re-anchors there)
    whole = simulation(t0)
    reference = settled_states(whole, 400)
    first = simulation(t0)
    settled_states(first, 137)
    kept = DynamicsSnapshot.from_values(snapshot(
        anchor=first.initial_time, steps=first.steps, dt=first.dt, q=tuple(first.q), qd=tuple(first.qd),
        motor_torque=first.motor_torque).to_values())
    second = simulation(kept.anchor)
    second.restore(kept.steps, np.array(kept.q), np.array(kept.qd))
    assert second.t == first.t
    second.outputs()
    continued = settled_states(second, 400)
    assert np.array_equal(np.array(continued), np.array(reference[137:])), 'the restored run differs'


@pytest.mark.parametrize('engine', [PYTHON, pytest.param(NUMBA, marks=pytest.mark.skipif(
    not kernel.available(), reason='numba is not installed'))])
def test_a_coulomb_simulation_restored_with_its_contact_state_continues_bit_for_bit(engine):
    """Two wheels sliding at the restored boundary: the contact state taken up with the state, the run goes on to
    the bit; a state that is no contact state is refused, the simulation as it was."""
    robot = Robot(load_robot_parameters())
    scenario = load_scenario('circle')
    q0, qd0 = scenario.initial_state(robot)

    def simulation() -> Simulation:
        sim = Simulation(robot, scenario.reference, ConstraintSelection.structural(trajectory=False), q0, qd0,
                         contact='coulomb', engine=engine)
        sim.set_motor_torque(1.0, -1.0)
        return sim

    reference = settled_states(simulation(), 60)
    first = simulation()
    settled_states(first, 25)
    held = first.contact_state
    assert held is not None and 0 < len(held.sliding) < 4
    second = simulation()
    second.restore(first.steps, first.q, first.qd, held)
    taken = second.contact_state
    assert taken.sliding == held.sliding and np.array_equal(taken.loads, held.loads)
    assert np.array_equal(taken.friction, held.friction)
    with pytest.raises(ParameterError, match='4 loads, 4 x 2 friction components and wheels 0..3'):
        second.restore(first.steps, first.q, first.qd, CoulombState(frozenset({4}), held.loads, held.friction))
    assert second.contact_state.sliding == held.sliding
    second.outputs()
    continued = settled_states(second, 60)
    assert np.array_equal(np.array(continued), np.array(reference[25:])), 'the restored run differs'
