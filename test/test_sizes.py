"""Small rooms: no module of the product over MAX_MODULE_LINES lines, no function over MAX_FUNCTION_LINES.

The compiled kernel keeps a few long functions: numba compiles one hot loop best as one function (a call between
jitted functions passes its arrays and state, and the loop's state stays in one compiled frame). Each is listed in
LONG_KERNEL_FUNCTIONS with why, and the list may not go stale: a listed function that is gone or has shrunk to
the limit fails as a function over it does.
"""

from __future__ import annotations

import ast
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ('wallbot_sim', 'wallbot_msgs_py')
MAX_MODULE_LINES = 400
MAX_FUNCTION_LINES = 60
KERNEL = 'wallbot_sim/model/batch/kernel'

LONG_KERNEL_FUNCTIONS = {
    f'{KERNEL}/boundary.py:_boundary': 'a stick/slip set solved at a boundary in one compiled frame',
    f'{KERNEL}/friction.py:_kinetic_equations': "Newton's residual and Jacobian in one pass, at every trial step",
    f'{KERNEL}/friction.py:_kinetic': "Newton's iteration and line search in one compiled frame",
    f'{KERNEL}/friction.py:_pressed_kinetic': "the loads' elimination and Newton's iteration in one compiled frame",
    f'{KERNEL}/linalg.py:_rank_revealing': "the rank-revealing least squares' stages share one frame's scratch",
    f'{KERNEL}/settle.py:_settle': "a round of stick/slip transitions keeps its sets in one compiled frame",
}
"""'path:function' of the kernel functions allowed over MAX_FUNCTION_LINES, with why numba needs them long."""


def _sources() -> list[Path]:
    return sorted(path for package in PACKAGES for path in (REPO_ROOT / package).rglob('*.py'))


def _name(path: Path) -> str:
    return path.relative_to(REPO_ROOT).as_posix()


def _function_lines() -> dict[str, int]:
    """'path:qualified name' of every function and method of the packages, and its length in lines (decorators
    and docstring included)."""
    lengths: dict[str, int] = {}

    def visit(node: ast.AST, prefix: str, path: str) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
                name = f'{prefix}{child.name}'
                if not isinstance(child, ast.ClassDef):
                    first = min([child.lineno] + [decorator.lineno for decorator in child.decorator_list])
                    lengths[f'{path}:{name}'] = child.end_lineno - first + 1
                visit(child, f'{name}.', path)
            else:
                visit(child, prefix, path)

    for path in _sources():
        visit(ast.parse(path.read_text(), str(path)), '', _name(path))
    return lengths


def test_the_packages_are_found():
    names = {_name(path) for path in _sources()}
    assert 'wallbot_sim/model/simulation.py' in names and 'wallbot_msgs_py/cdr.py' in names


def test_no_module_is_over_the_limit():
    long = {_name(path): count for path in _sources()
            if (count := len(path.read_text().splitlines())) > MAX_MODULE_LINES}
    assert not long, f'modules over {MAX_MODULE_LINES} lines (split them by concern): {long}'


def test_no_function_is_over_the_limit_but_the_listed_kernel_ones():
    long = {name: count for name, count in _function_lines().items()
            if count > MAX_FUNCTION_LINES and name not in LONG_KERNEL_FUNCTIONS}
    assert not long, f'functions over {MAX_FUNCTION_LINES} lines: {long}'


def test_every_listed_kernel_function_exists_and_is_still_long():
    lengths = _function_lines()
    stale = {name: lengths.get(name) for name in LONG_KERNEL_FUNCTIONS
             if lengths.get(name, 0) <= MAX_FUNCTION_LINES}
    assert not stale, f'listed as long but gone (None) or within the limit, remove them from the list: {stale}'


def test_the_listed_exceptions_are_kernel_functions_that_say_why_they_are_long():
    for name in LONG_KERNEL_FUNCTIONS:
        path, function = name.split(':')
        assert path.startswith(f'{KERNEL}/'), f'{name}: only the compiled kernel may keep long functions'
        lines = (REPO_ROOT / path).read_text().splitlines()
        start = next(number for number, line in enumerate(lines) if line.startswith(f'def {function}('))
        comment = ' '.join(line for line in lines[max(start - 3, 0):start] if line.startswith('#'))
        assert 'long' in comment.lower(), f'{name}: say in a comment above the function why it is long'
