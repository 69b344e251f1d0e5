"""One thread for Numba-parallel kernels launched on few items (benchmarks/README.md, "Serial path
for small systems").

A ``prange`` kernel wakes Numba's worker threads at every call. On an idle machine that costs
tens of microseconds; with another busy process on these 2-core machines a woken worker often
waits a whole scheduler time slice for a core: 6-8 ms a call, measured, while the cohesive points
of a 1e3-1e5-dof model take 0.02-0.3 ms on one thread. Below a size threshold per kernel the call
runs with Numba's thread count set to 1 for the calling thread only (``numba.set_num_threads``, a
thread-local setting costing a few microseconds, restored afterwards): the same compiled kernel,
the same arithmetic (every ``prange`` item is independent, so the result is bit for bit the same).

Thresholds: the item count (points or cells) whose one-thread time is about 4-5 ms. Measured with
the machine otherwise nearly idle (load 0.6, 20 ms pauses between calls as in a Newton loop), one
thread was faster up to 4096 Drucker-Prager cells (3.4 against 5.7 ms a call), two from 8100
(4.3 against 7.0 ms).
"""

from __future__ import annotations

import numba as nb

COHESIVE_POINTS = 5000  # CSE point pairs (ep_points, rp_points): up to about 1 us each on one thread
SOLID_CELLS = 5000  # Drucker-Prager and EDE cells (dp_blocks, ede_blocks): about 0.85 us each and up


def serial_below(n_items: int, below: int, kernel, *args):
    """``kernel(*args)``, on one Numba thread if ``n_items < below``; returns what it returns."""
    if n_items >= below:
        return kernel(*args)
    previous = nb.get_num_threads()
    if previous == 1:
        return kernel(*args)
    nb.set_num_threads(1)
    try:
        return kernel(*args)
    finally:
        nb.set_num_threads(previous)
