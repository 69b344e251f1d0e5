"""Item-parallel kernels that wake threads only where it pays: one rule for every ``prange`` kernel.

A ``prange`` kernel wakes Numba's worker threads at every call. On an idle machine that costs tens
of microseconds; with another busy process on these 2-core machines a woken worker often waits a
whole scheduler time slice for a core: 6-8 ms a call, measured, while the cohesive points of a
1e3-1e5-dof model take 0.02-0.3 ms on one thread (benchmarks/README.md, "Serial path for small
systems"). So every item-parallel kernel of the package is declared with :func:`parallel_kernel`,
and the rule is the same for all of them: a call whose one-thread work (items x the kernel's
measured cost per item) is below :data:`SERIAL_WORK` runs the kernel compiled *without*
``parallel=True``, from the calling thread; a larger call runs the ``prange`` version on Numba's
threads. Both versions come from the same Python function and are compiled lazily, on their first
call: a run of small problems (the paper's study) never compiles the parallel one, which costs
3-5x the serial one to compile (benchmarks/README.md, "First run"). Every ``prange`` item writes
only its own outputs, so both versions give the same bits (tested).

``FORCE`` ("serial", "parallel" or None) overrides the rule for every kernel (tests, benchmarks).
"""

from __future__ import annotations

import types
from collections.abc import Callable
from typing import Any

import numba as nb

from rockfrac.compiled import OPTIONS

SERIAL_WORK = 4.0e-3  # s of one-thread work below which a call stays on the calling thread
FORCE: str | None = None  # "serial" | "parallel": every kernel on that path (tests and benchmarks)

KERNELS: list[ParallelKernel] = []  # every kernel declared with parallel_kernel, for the tests


def _renamed(func: Callable, suffix: str) -> Callable:
    """A copy of ``func`` with ``suffix`` added to its qualified name: Numba keys its on-disk cache
    by module, qualified name and line, not by compile options, so the serial and the parallel
    compilations of one function need distinct names."""
    copy = types.FunctionType(func.__code__, func.__globals__, func.__name__ + suffix, func.__defaults__,
                              func.__closure__)
    copy.__qualname__ = func.__qualname__ + suffix
    copy.__doc__ = func.__doc__
    copy.__module__ = func.__module__
    return copy


class ParallelKernel:
    """A ``prange`` kernel: serial below ``below`` items (``args[items_arg].shape[0]``), else parallel."""

    def __init__(self, func: Callable, cost: float, items_arg: int, cache: bool = True):
        self.py_func = func
        self.cost = cost  # s per item on one thread (measured: benchmarks/kernels.py --threads-rule)
        self.items_arg = items_arg
        self.below = max(1, int(SERIAL_WORK / cost))
        self.serial: Any = nb.njit(cache=cache, **OPTIONS)(_renamed(func, "__serial"))
        self.parallel: Any = nb.njit(cache=cache, parallel=True, **OPTIONS)(func)
        self.__doc__ = func.__doc__
        self.__name__ = func.__name__
        self.__qualname__ = func.__qualname__
        self.__module__ = func.__module__

    def items(self, args: tuple) -> int:
        return int(args[self.items_arg].shape[0])

    def path(self, n_items: int) -> str:
        """'serial' or 'parallel': the version a call on n_items runs."""
        if FORCE is not None:
            return FORCE
        return "serial" if n_items < self.below else "parallel"

    def __call__(self, *args):
        if self.path(self.items(args)) == "serial":
            return self.serial(*args)
        return self.parallel(*args)

    def __repr__(self) -> str:
        return f"<parallel_kernel {self.__module__}.{self.__qualname__}: serial below {self.below} items>"


def parallel_kernel(cost: float, items_arg: int = 0) -> Callable[[Callable], ParallelKernel]:
    """Declare an item-parallel Numba kernel (its loop over items a ``prange``) costing ``cost``
    seconds per item on one thread; items = ``args[items_arg].shape[0]``. See the module note."""
    if not cost > 0.0:
        raise ValueError(f"cost per item must be > 0 s, got {cost!r}")

    def declare(func: Callable) -> ParallelKernel:
        kernel = ParallelKernel(func, cost, items_arg)
        KERNELS.append(kernel)
        return kernel

    return declare
