"""Every place that lists the constraint modules follows the one table, ``wallbot_msgs_py.constraint_modules``: the
model's modules, ``ConstraintSelection``'s fields and labels, the batch's modules, the compiled kernel's flags and
rows, constraint_config's parameters, the ``constraints`` message and the state snapshot."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from model_helpers import random_parameters
from wallbot_msgs_py import bagio, snapshot, topics
from wallbot_msgs_py.constraint_modules import (
    CONSTRAINT_MODULES, CONSTRAINT_SWITCHES, STACKING_ORDER, STRUCTURAL, TASKS)
from wallbot_sim import messages
from wallbot_sim.model import ConstraintSelection, Robot
from wallbot_sim.model.batch import kernel
from wallbot_sim.model.batch.constraints import BATCH_MODULES, BatchGains
from wallbot_sim.model.batch.kernel import problem as kernel_problem
from wallbot_sim.model.batch.robots import RobotBatch
from wallbot_sim.model.constraint_set import MODULES, make_module
from wallbot_sim.model.constraints import WHEEL_DIRECTIONS, BaumgarteGains
from wallbot_sim.model.robot import DOF
from wallbot_sim.model.trajectories import Circle
from wallbot_sim.settings.config import CONSTRAINT_CONFIG

ALL_ON = ConstraintSelection(**dict.fromkeys(CONSTRAINT_MODULES, True))
REFERENCE = Circle(radius=0.7, period=9.0, center=(0.2, -0.1))
GAINS = BaumgarteGains(4.0, 6.0)


@pytest.fixture(scope='module')
def robot() -> Robot:
    return Robot(random_parameters(np.random.default_rng(33)))


@pytest.fixture(scope='module')
def state() -> tuple[float, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(7)
    return 1.3, rng.normal(0.0, 1.0, DOF), rng.normal(0.0, 1.0, DOF)


def test_the_table_orders_the_tasks_first_then_the_paper_structural_constraints():
    assert STACKING_ORDER == ('trajectory', 'tangent_heading', 'belt', 'non_lateral', 'nonslip')
    assert set(TASKS) | set(STRUCTURAL) == set(CONSTRAINT_MODULES) and not set(TASKS) & set(STRUCTURAL)
    assert len(set(CONSTRAINT_SWITCHES)) == len(CONSTRAINT_MODULES)


def test_the_models_modules_are_the_tables_in_stacking_order(robot, state):
    """Each module built for a robot is the one its name says, a task exactly where the table says so, with the
    row count its kind declares (what the kernel lays out)."""
    assert tuple(MODULES) == STACKING_ORDER
    t, q, qd = state
    for name, kind in MODULES.items():
        assert kind.task == CONSTRAINT_MODULES[name].task, name
        module = make_module(name, robot, REFERENCE, GAINS)
        assert module.name == name
        rows, rhs = module.rows(t, q, qd)
        assert rows.shape == (kind.rows, DOF) and rhs.shape == (kind.rows,), name


def test_the_selection_has_one_field_per_module_in_the_tables_order():
    assert tuple(field.name for field in dataclasses.fields(ConstraintSelection)) == tuple(CONSTRAINT_MODULES)
    assert ALL_ON.active_names() == list(STACKING_ORDER)
    assert ALL_ON.label() == '+'.join(STACKING_ORDER)
    assert ConstraintSelection.structural(trajectory=False).active_names() == list(STRUCTURAL)
    assert ConstraintSelection.parse(','.join(reversed(STRUCTURAL))).active_names() == list(STACKING_ORDER)


def test_the_batchs_modules_are_the_models(robot, state):
    """Every module has its batched form under the same name, with the model's rows robot by robot."""
    assert set(BATCH_MODULES) == set(MODULES)
    t, q, qd = state
    robots = RobotBatch([robot, robot])
    gains = BatchGains(np.full(2, GAINS.alpha), np.full(2, GAINS.beta))
    for name, build in BATCH_MODULES.items():
        module = build(robots, REFERENCE, gains)
        assert module.name == name
        rows, rhs = module.rows(t, np.array([q, q]), np.array([qd, qd]))
        single_rows, single_rhs = make_module(name, robot, REFERENCE, GAINS).rows(t, q, qd)
        np.testing.assert_allclose(rows[1], single_rows, rtol=1e-12, atol=1e-12, err_msg=name)
        np.testing.assert_allclose(rhs[1], single_rhs, rtol=1e-12, atol=1e-12, err_msg=name)


def test_the_kernels_flags_and_rows_are_the_models(robot, state):
    """Module by module, the kernel's problem with that flag alone has the Python module's rows, and its row
    count is the one ``module_flags`` counts."""
    assert kernel.MODULE_ORDER == STACKING_ORDER
    assert kernel.MODULE_ROWS == tuple(kind.rows for kind in MODULES.values())
    t, q, qd = state
    constants = kernel.robot_constants(RobotBatch([robot]), np.array([GAINS.alpha]), np.array([GAINS.beta]))[0]
    reference = kernel.reference_samples(REFERENCE, t, 0, 1, 1e-3)[0, 0]
    problem = getattr(kernel_problem._problem, 'py_func', kernel_problem._problem)
    for name in STACKING_ORDER:
        flags, count = kernel.module_flags((name,))
        rows, rhs = np.zeros((kernel.MAX_ROWS, DOF)), np.zeros(kernel.MAX_ROWS)
        written = problem(q, qd, reference, flags, constants, np.zeros(2), np.zeros(4), False, np.zeros(4, np.bool_),
                          np.zeros(8), rows, rhs, np.zeros((DOF, DOF)), np.zeros(DOF))
        single_rows, single_rhs = make_module(name, robot, REFERENCE, GAINS).rows(t, q, qd)
        assert written == count == MODULES[name].rows, name
        np.testing.assert_allclose(rows[:written], single_rows, rtol=1e-12, atol=1e-12, err_msg=name)
        np.testing.assert_allclose(rhs[:written], single_rhs, rtol=1e-12, atol=1e-12, err_msg=name)
    every, most = kernel.module_flags(STACKING_ORDER)
    assert every.all() and most == sum(kind.rows for kind in MODULES.values()) <= kernel.MAX_ROWS


def test_the_kernel_holds_each_contact_direction_by_the_module_whose_friction_holds_it(robot):
    for row, flag in enumerate(kernel.HELD_BY):
        module = make_module(kernel.MODULE_ORDER[flag], robot, REFERENCE, GAINS)
        assert module.direction == WHEEL_DIRECTIONS[row]


def test_constraint_config_declares_one_switch_per_module():
    for name, switch in CONSTRAINT_MODULES.items():
        setting = CONSTRAINT_CONFIG[switch.parameter]
        assert (setting.default, setting.help) == (switch.default, switch.description), name
    switches = [name for name in CONSTRAINT_CONFIG.names if name in CONSTRAINT_SWITCHES]
    assert tuple(switches) == CONSTRAINT_SWITCHES


def test_the_messages_carry_the_tables_switches_in_its_order():
    """The ``constraints`` message holds every switch in the table's order, then the gains and the active modules in
    stacking order, under the label that joins them; the snapshot keeps the switches in the table's order."""
    switches = messages.switches_from_selection(ALL_ON)
    assert tuple(switches) == CONSTRAINT_SWITCHES
    status = bagio.deserialize(messages.constraints_message(switches, GAINS), topics.CONSTRAINTS.type)
    keys = [value.key for value in status.values]
    assert tuple(keys[:len(CONSTRAINT_SWITCHES)]) == CONSTRAINT_SWITCHES
    assert dict((value.key, value.value) for value in status.values)['active'] == ','.join(STACKING_ORDER)
    assert status.message == '+'.join(STACKING_ORDER)
    assert snapshot.SWITCHES == CONSTRAINT_SWITCHES
