"""The suite waits for conditions, never for times: a ``time.sleep`` followed by an assertion is a
test that hopes the machine was fast enough. Sleeps inside a loop are polls (the loop's condition
is the event); the few deliberate sleeps outside one are listed here with why."""

from __future__ import annotations

import ast
from pathlib import Path

TEST_DIR = Path(__file__).resolve().parent

DELIBERATE = {
    ('test_faults.py', 'test_each_node_killed_and_restarted_once'):
        'the outage itself: the killed dynamics stays dead for DOWN before it is restarted',
    ('test_faults.py', 'test_reset_and_a_kill_in_a_closed_loop_every_node_carries_on'):
        'the outage itself: the killed dynamics stays dead for DOWN before it is restarted',
    ('test_two_hosts.py', 'test_one_second_link_outage_mid_run_and_recovery'):
        'the outage itself: the link between the hosts is down for 1 s',
}
"""(file, function) -> why it sleeps before asserting. The assertions after each are about what the
system reports once the outage is over, not about what happened during a fixed time."""


def _is_sleep(node: ast.stmt) -> bool:
    if not (isinstance(node, ast.Expr) and isinstance(node.value, ast.Call)):
        return False
    func = node.value.func
    return (isinstance(func, ast.Attribute) and func.attr == 'sleep') or (isinstance(func, ast.Name) and func.id == 'sleep')


def _asserts(statements: list[ast.stmt]) -> bool:
    return any(isinstance(node, ast.Assert) for statement in statements for node in ast.walk(statement))


def _blocks(node: ast.AST) -> list[list[ast.stmt]]:
    """The statement lists directly inside ``node`` (not inside a nested loop or function)."""
    return [getattr(node, field) for field in ('body', 'orelse', 'finalbody')
            if isinstance(getattr(node, field, None), list)] + \
        [handler.body for handler in getattr(node, 'handlers', [])] + \
        [case.body for case in getattr(node, 'cases', [])]


def sleeps_then_asserts(tree: ast.AST) -> list[tuple[str, int]]:
    """(function, line) of each sleep outside a loop that an assert follows in its block."""
    found: list[tuple[str, int]] = []

    def visit(node: ast.AST, function: str) -> None:
        for block in _blocks(node):
            for index, statement in enumerate(block):
                if _is_sleep(statement) and _asserts(block[index + 1:]):
                    found.append((function, statement.lineno))
                if isinstance(statement, (ast.FunctionDef, ast.AsyncFunctionDef)):
                    visit(statement, statement.name)
                elif isinstance(statement, ast.ClassDef):
                    visit(statement, function)
                elif not isinstance(statement, (ast.For, ast.AsyncFor, ast.While)):
                    visit(statement, function)  # with, try, if: their blocks; a loop's sleep is a poll
    visit(tree, '<module>')
    return found


def test_no_test_sleeps_a_fixed_time_and_then_asserts():
    offenders = []
    for path in sorted(TEST_DIR.glob('*.py')):
        for function, line in sleeps_then_asserts(ast.parse(path.read_text(), str(path))):
            if (path.name, function) not in DELIBERATE:
                offenders.append(f'{path.name}:{line} in {function}')
    assert not offenders, ('a fixed sleep followed by an assertion (wait for an event the system reports, '
                           'or list it in DELIBERATE with why): ' + ', '.join(offenders))


def test_the_check_finds_a_sleep_before_an_assert_and_passes_a_poll():
    hoping = ast.parse('def t():\n    held = f()\n    time.sleep(0.3)\n    assert f() == held\n')
    polling = ast.parse('def t():\n    while not f():\n        time.sleep(0.02)\n    assert f()\n')
    nested = ast.parse('def t():\n    with g():\n        if h():\n            sleep(1)\n            x = 1\n'
                       '        assert x\n')
    assert sleeps_then_asserts(hoping) == [('t', 3)]
    assert sleeps_then_asserts(polling) == []
    assert sleeps_then_asserts(nested) == []  # the assert is outside the sleep's block...
    inner = ast.parse('def t():\n    with g():\n        sleep(1)\n        if h():\n            assert x\n')
    assert sleeps_then_asserts(inner) == [('t', 3)]  # ...but one nested after it in the same block counts


def test_every_deliberate_sleep_is_still_there():
    """A listed sleep that went away takes its line out of DELIBERATE (the list stays short and true)."""
    found = {(path.name, function) for path in TEST_DIR.glob('*.py')
             for function, _line in sleeps_then_asserts(ast.parse(path.read_text(), str(path)))}
    assert set(DELIBERATE) <= found, sorted(set(DELIBERATE) - found)
