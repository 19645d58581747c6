"""numba for the kernel's modules, with a cache that one stamp of the whole package invalidates.

numba's cache of a function is checked against its own file only, while a kernel function compiles the functions it
calls from the package's other files into its own code: a change to a callee in another file would leave its
callers' cached code in use. The kernel's functions are therefore cached under a stamp of every source file of the
package (a digest of their contents, taken at import, as the code that runs is the code imported) and of the
constraint modules' table (their order and rows, compiled in as constants: ``layout.MODULE_ORDER``), so that any
change recompiles them all. numba is optional: without it ``jit`` returns the function as written.
"""

from __future__ import annotations

import hashlib
from pathlib import Path
from typing import Any, Callable

import numpy as np

from wallbot_sim.model.constraint_set import MODULES

try:
    import numba
    from numba import prange, types
    from numba.core import caching, cgutils
    from numba.extending import intrinsic
except ImportError:  # the NumPy path needs nothing more
    numba = None
    prange = range

PACKAGE = Path(__file__).resolve().parent
"""The kernel's package directory."""


def package_stamp() -> str:
    """A digest of every source file of the package, by name and contents, and of the modules' names and rows."""
    digest = hashlib.sha256()
    for path in sorted(PACKAGE.glob('*.py')):
        digest.update(path.name.encode())
        digest.update(path.read_bytes())
    digest.update(repr([(name, kind.rows) for name, kind in MODULES.items()]).encode())
    return digest.hexdigest()


def available() -> bool:
    """Whether numba imported (the compiled engine can run)."""
    return numba is not None


def _stamped(locator: type) -> type:
    """numba's cache locator ``locator`` for the package's functions alone, stamped by ``package_stamp``."""

    class PackageStamped(locator):
        def get_source_stamp(self) -> str:
            return STAMP

        @classmethod
        def from_function(cls, py_func: Callable, py_file: str) -> Any:
            if Path(py_file).resolve().parent != PACKAGE:
                return None
            return super().from_function(py_func, py_file)

    PackageStamped.__name__ = PackageStamped.__qualname__ = f'PackageStamped{locator.__name__}'
    return PackageStamped


if numba is not None:
    STAMP = package_stamp()
    caching.CacheImpl._locator_classes[:0] = [_stamped(locator) for locator in (
        caching.UserProvidedCacheLocator, caching.InTreeCacheLocator, caching.UserWideCacheLocator)]


def jit(function: Any, **options: Any) -> Any:
    """``function`` compiled by numba, cached; as written without numba."""
    # error_model 'numpy': a division by zero gives inf or NaN as in NumPy, unchecked (the caller checks the results)
    return numba.njit(cache=True, error_model='numpy', **options)(function) if numba is not None else function


def _identity(array: np.ndarray) -> np.ndarray:
    """``array`` itself: without numba there are no reference counts to skip."""
    return array


if numba is not None:
    @intrinsic
    def _data_of(typing_context: Any, array: Any) -> Any:
        """The address of a C-contiguous array's first element: a raw pointer, no reference to the array."""
        if not isinstance(array, types.Array) or array.layout != 'C':
            return None

        def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
            data = context.make_array(signature.args[0])(context, builder, args[0]).data
            return builder.bitcast(data, cgutils.voidptr_t)
        return types.voidptr(array), codegen

    def _raw_view(array: np.ndarray) -> np.ndarray:
        """``array``'s elements as a new array that owns nothing (``numba.carray`` of its data)."""
        return numba.carray(_data_of(array), array.shape, array.dtype)

unowned = jit(_raw_view, inline="always") if numba is not None else _identity
"""A view of a C-contiguous array without its reference count, in compiled code: every view of it and every call it
is passed to then skips numba's two atomic counts (some 20 arrays go through each call of a boundary: the counts
were half of a coulomb step). The caller must hold the array while the view is in use: take the view of an
argument, never of an array the function itself allocates. Without numba, the array itself."""
