"""How rockfrac compiles its Numba functions: ``kernel`` (callable from Python) and ``inner`` (only
from other compiled functions), both cached on disk and neither with a C-callable wrapper.

Numba gives every compiled function two wrappers besides its body: a CPython entry point (unboxing
the arguments of a Python call) and a C-callable one (for first-class function pointers, which
rockfrac never takes). Both are lowered, optimised and turned into machine code with the function,
and, because a caller links in its callees' whole modules, again in every caller up the chain. A
function only ever called from compiled code needs neither. On the paper's study the wrappers were
a tenth of the first run's compiling (benchmarks/README.md, "First run").

``inner`` functions have no Python entry point: Numba would crash the interpreter on a Python call
to one, so their dispatcher refuses such a call with a ``TypeError`` instead. Which functions may
be ``inner`` is checked from the sources (``tests/test_compiled.py``): none is referenced outside a
compiled function's body.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numba as nb
from numba.core import config
from numba.core.registry import CPUDispatcher

OPTIONS: dict[str, Any] = {"no_cfunc_wrapper": True, "error_model": "numpy"}  # Numba options of both kinds


def kernel(func: Callable | None = None, **options: Any) -> Any:
    """A compiled function callable from Python and from compiled code (``@kernel`` or
    ``@kernel(fastmath=...)``), cached on disk."""
    if func is None:
        return lambda f: kernel(f, **options)
    return nb.njit(cache=True, **{**OPTIONS, **options})(func)


class InnerDispatcher(CPUDispatcher):
    """A Numba dispatcher without a Python entry point: compiled callers only."""

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        name = f"{self.py_func.__module__}.{self.py_func.__qualname__}"
        raise TypeError(f"{name} is compiled for compiled callers only (rockfrac.compiled.inner): it has no "
                        "Python entry point; call the kernel that uses it")


def inner(func: Callable) -> Any:
    """A compiled function called only from other compiled functions, cached on disk."""
    if config.DISABLE_JIT:  # type: ignore[attr-defined]
        return func
    disp = InnerDispatcher(py_func=func, locals={},
                           targetoptions={**OPTIONS, "nopython": True, "no_cpython_wrapper": True})
    disp.enable_caching()
    return disp
