"""The kernel's numba cache: one stamp of the whole package, so that a change to any of its files recompiles every
kernel function (a function compiles its callees from the package's other files into its own code)."""

from __future__ import annotations

import importlib.util
import shutil
import sys
from dataclasses import replace

import pytest

from wallbot_sim.model.batch import kernel
from wallbot_sim.model.batch.kernel import boundary, compiling, dynamics, friction, layout, linalg, settle

pytestmark = pytest.mark.skipif(not kernel.available(), reason='numba is not installed')


def test_every_kernel_function_is_cached_under_the_package_stamp():
    from numba.core.registry import CPUDispatcher
    dispatchers = [value for module in (boundary, dynamics, friction, layout, linalg, settle)
                   for value in vars(module).values() if isinstance(value, CPUDispatcher)]
    assert len(dispatchers) > 40
    for dispatcher in dispatchers:
        assert dispatcher._cache._impl.locator.get_source_stamp() == compiling.STAMP == compiling.package_stamp()


def test_a_change_to_any_file_of_the_package_changes_the_stamp(tmp_path, monkeypatch):
    copy = tmp_path / 'kernel'
    shutil.copytree(compiling.PACKAGE, copy, ignore=shutil.ignore_patterns('__pycache__'))
    monkeypatch.setattr(compiling, 'PACKAGE', copy)
    assert compiling.package_stamp() == compiling.STAMP
    for path in sorted(copy.glob('*.py')):
        text = path.read_text()
        path.write_text(text + '\n')
        assert compiling.package_stamp() != compiling.STAMP, path.name
        path.write_text(text)


def test_a_change_to_the_constraint_modules_order_or_rows_changes_the_stamp(monkeypatch):
    """The modules' flags and rows are compiled in as constants from outside the package (``layout.MODULE_ORDER``)."""
    modules = compiling.MODULES
    monkeypatch.setattr(compiling, 'MODULES', dict(reversed(modules.items())))
    assert compiling.package_stamp() != compiling.STAMP
    name, kind = next(iter(modules.items()))
    monkeypatch.setattr(compiling, 'MODULES', {**modules, name: replace(kind, rows=kind.rows + 1)})
    assert compiling.package_stamp() != compiling.STAMP
    monkeypatch.undo()
    assert compiling.package_stamp() == compiling.STAMP


def test_functions_outside_the_package_keep_numbas_own_cache(tmp_path):
    source = tmp_path / 'elsewhere.py'
    source.write_text('import numba\n\n\n@numba.njit(cache=True)\ndef twice(x):\n    return 2 * x\n')
    spec = importlib.util.spec_from_file_location('elsewhere', source)
    module = importlib.util.module_from_spec(spec)
    sys.modules['elsewhere'] = module
    try:
        spec.loader.exec_module(module)
        locator = module.twice._cache._impl.locator
        assert not type(locator).__name__.startswith('PackageStamped')
        assert locator.get_source_stamp() != compiling.STAMP
    finally:
        del sys.modules['elsewhere']


def test_an_unowned_view_is_the_array_itself_and_a_strided_array_is_refused():
    import numba
    import numpy as np

    @numba.njit
    def write_through(array):
        view = compiling.unowned(array)
        view[1, 2] = 5.0
        return view.shape[0] * 10 + view.shape[1]

    owner = np.zeros((3, 4))
    assert write_through(owner) == 34
    assert owner[1, 2] == 5.0 and np.count_nonzero(owner) == 1  # the same memory, no copy

    @numba.njit
    def column_of(array):
        return compiling.unowned(array[:, 1])[0]

    with pytest.raises(numba.core.errors.TypingError, match='_data_of'):  # a raw view needs C order
        column_of(owner)
