"""The serial path for small systems (benchmarks/README.md, "Serial path for small systems"):
PARDISO on one MKL thread below ``Pardiso.serial_below`` rows (thread-local, restored after each
call, MKL's default where the symbol is missing), Numba kernels on one thread below their item
thresholds (``rockfrac.threads``, tested in test_threads.py), Newton's norms without BLAS; the same results either way."""

import math
import os
import subprocess
import sys
import threading
import types

import numba as nb
import numpy as np
import pytest
import scipy.sparse as sp
from conftest import paper_case

from rockfrac import threads
from rockfrac.case.build import build
from rockfrac.case.schema import parse_case
from rockfrac.runner import history_row
from rockfrac.solve import linear
from rockfrac.model import serial_dot as _dot
from rockfrac.solve.newton import NewtonOptions
from rockfrac.solve.stepping import SteppingOptions, run_stages

needs_pardiso = pytest.mark.skipif("pardiso" not in linear.available(), reason="pypardiso not installed")


def tridiagonal(n: int) -> sp.csr_matrix:
    return sp.diags([np.full(n - 1, -1.0), np.full(n, 4.0), np.full(n - 1, -1.5)], [-1, 0, 1], format="csr")


def mkl_default(lib) -> int:
    """MKL's process-wide thread count: read on a fresh thread (the setting is thread-local)."""
    out = []
    t = threading.Thread(target=lambda: out.append(lib.MKL_Get_Max_Threads()))
    t.start()
    t.join()
    return out[0]


def recorded_threads(solver: linear.Pardiso, a: sp.csr_matrix) -> tuple[list[int], int, int, np.ndarray]:
    """MKL's process-wide thread count, the count inside every PARDISO call of a release, an
    analysis, a factorization and a solve, the count on this thread after them; and the solution."""
    solver.factorize(a)  # loads the runtime (the first analysis)
    lib = solver._solver.libmkl
    inner = solver._solver._mkl_pardiso
    seen = []

    def wrapped(*args):
        seen.append(lib.MKL_Get_Max_Threads())
        return inner(*args)

    before = mkl_default(lib)
    solver._solver._mkl_pardiso = wrapped
    try:
        solver.begin_step()  # analysis, factorization and solve all seen
        x = solver.factorize(a).solve(np.ones(a.shape[0]))
    finally:
        solver._solver._mkl_pardiso = inner
    return seen, before, lib.MKL_Get_Max_Threads(), x


@needs_pardiso
def test_mkl_thread_local_symbol_is_found_here():
    solver = linear.Pardiso()
    solver.factorize(tridiagonal(600))
    assert solver._set_threads_local is not None
    assert solver._set_threads_local.__name__ == "MKL_Set_Num_Threads_Local"


@needs_pardiso
def test_pardiso_runs_one_thread_below_the_threshold_and_mkl_default_above():
    a = tridiagonal(600)
    small = linear.Pardiso()
    assert a.shape[0] < small.serial_below
    seen, default, after, x_serial = recorded_threads(small, a)
    if default < 2:
        pytest.skip("MKL runs one thread here anyway")
    assert len(seen) == 4 and set(seen) == {1} and small.threads_used == 1  # phases -1, 11, 22, 33
    assert after == default  # the thread-local setting restored
    large = linear.Pardiso()
    large.serial_below = 100  # the same matrix counts as large
    seen, _, after, x_threaded = recorded_threads(large, a)
    assert set(seen) == {default} and after == default and large.threads_used == 0
    at_threshold = linear.Pardiso()  # the class's threshold: a system of that many rows is large
    seen, _, _, _ = recorded_threads(at_threshold, tridiagonal(linear.Pardiso.serial_below))
    assert set(seen) == {default} and at_threshold.threads_used == 0
    # different thread counts may round differently; this system is well conditioned
    assert np.abs(x_serial - x_threaded).max() <= 1e-14 * np.abs(x_serial).max()
    assert np.abs(a @ x_serial - 1.0).max() < 1e-13


@needs_pardiso
def test_a_small_pardiso_system_starts_no_mkl_threads():
    """MKL's OpenMP pool is created at its first parallel region: in a fresh process a small
    system must not create it; the same system with the threshold at 0 then does (where MKL has
    more than one thread)."""
    code = """if True:
        import os
        import numpy as np
        import scipy.sparse as sp
        from rockfrac.solve.linear import Pardiso
        n = 3000
        a = sp.diags([np.full(n - 1, -1.0), np.full(n, 4.0), np.full(n - 1, -1.0)], [-1, 0, 1], format="csr")
        count = [len(os.listdir("/proc/self/task"))]
        for below in (30_000, 0):
            p = Pardiso()
            p.serial_below = below
            p.factorize(a).solve(np.ones(n))
            count.append(len(os.listdir("/proc/self/task")))
        print(*count, p._solver.libmkl.MKL_Get_Max_Threads())
    """
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    start, after_serial, after_threaded, mkl_threads = (int(v) for v in out.stdout.split())
    assert after_serial == start
    if mkl_threads > 1:
        assert after_threaded > start


@needs_pardiso
def test_without_the_symbol_pardiso_keeps_mkl_default(monkeypatch):
    found = linear.Pardiso._threads_function
    monkeypatch.setattr(linear.Pardiso, "_threads_function",
                        staticmethod(lambda libmkl: found(types.SimpleNamespace())))  # an MKL without it
    solver = linear.Pardiso()
    a = tridiagonal(600)
    seen, default, after, x = recorded_threads(solver, a)
    assert solver._set_threads_local is None and solver.threads_used == 0
    assert set(seen) == {default} and after == default  # MKL's own setting throughout
    assert np.abs(a @ x - 1.0).max() < 1e-13


@pytest.mark.parametrize("n", [1000, 10_000, 100_000, 1_000_000])
def test_newton_norms_equal_numpy(n):
    def _norm(v):
        return math.sqrt(_dot(v, v))

    x = np.random.default_rng(n).standard_normal(n)
    y = np.random.default_rng(n + 1).standard_normal(n)
    assert abs(_norm(x) - np.linalg.norm(x)) <= 1e-14 * np.linalg.norm(x)
    assert abs(_dot(x, y) - x @ y) <= 1e-14 * np.linalg.norm(x) * np.linalg.norm(y)
    assert math.isnan(_norm(np.array([1.0, np.nan]))) and _norm(np.array([np.inf, 1.0])) == np.inf


def run(case: dict, serial: bool, monkeypatch) -> tuple[np.ndarray, np.ndarray]:
    """(load factor, axial force, Newton iterations) per step and the final displacements of a run
    with the serial path everywhere (serial) or nowhere (every threshold 0)."""
    built = build(parse_case(case, "t.toml"))
    solver = linear.make_solver("auto")
    pardiso = solver.first if isinstance(solver, linear.Checked) else solver  # PARDISO, checked under 'auto'
    pardiso.serial_below = 10**9 if serial else 0  # read by PARDISO only
    monkeypatch.setattr(threads, "FORCE", "serial" if serial else "parallel")
    rows = []
    run_stages(built.model, built.stages, solver, NewtonOptions(), SteppingOptions(),
               lambda info: rows.append((info.load_factor, history_row(built, info, None)["F_axial"],
                                         info.newton.iterations, info.u.copy())))
    return np.array([r[:3] for r in rows]), rows[-1][3]


def specimen_case(kind: str) -> dict:
    if kind == "ep cse":
        case = paper_case("ep", k=1e9, axial_steps=12)  # past the peak: 8 of 12 steps plastic
        case["mesh"].update(nx=6, ny=6)
        return case
    return {"mesh": {"kind": "specimen", "crack": False, "nx": 6, "ny": 6},
            "bulk": {"model": "drucker_prager", "E": 1.5e7, "nu": 0.3, "beta": 0.480385, "b": 0.321597,
                     "kappa0": 7532.54, "H": 43802.9},
            "loading": {"confinement": 2e4, "confinement_steps": 1, "axial_displacement": 2e-3, "axial_steps": 5}}


@pytest.mark.parametrize("kind", ["ep cse", "drucker-prager"])
def test_serial_and_threaded_paths_give_the_same_run(kind, monkeypatch):
    """Same steps, same Newton iterations, forces and displacements equal to 1e-10 relative (only
    PARDISO's thread count may change the rounding; the Numba kernels are bit for bit the same)."""
    serial, u_serial = run(specimen_case(kind), True, monkeypatch)
    threaded, u_threaded = run(specimen_case(kind), False, monkeypatch)
    assert serial.shape == threaded.shape and np.array_equal(serial[:, 2], threaded[:, 2])
    assert serial[:, 2].max() >= 4  # plastic steps: the return maps ran
    assert np.abs(serial[:, 1] - threaded[:, 1]).max() <= 1e-10 * np.abs(serial[:, 1]).max()
    assert np.abs(u_serial - u_threaded).max() <= 1e-10 * np.abs(u_serial).max()


@needs_pardiso
def test_results_do_not_depend_on_whether_numba_threads_ran_first():
    """MKL picks its threading layer when it loads, GNU's if Numba's OpenMP pool is already in the
    process: the two give different last bits. rockfrac fixes the layer (linear._choose_mkl_threading),
    so a fresh run equals a run after a parallel kernel, bit for bit."""
    code = """if True:
        import hashlib, sys
        import numpy as np
        if sys.argv[1] == "threads first":
            from rockfrac.fem import kinematics
            kinematics.strains.parallel(np.zeros((2, 1, 4, 2)), np.zeros((2, 8)))
        from rockfrac.case.build import build
        from rockfrac.case.schema import parse_case
        from rockfrac.solve import linear
        from rockfrac.solve.newton import NewtonOptions
        from rockfrac.solve.stepping import SteppingOptions, run_stages
        from rockfrac.studies import table1
        built = build(parse_case(table1.cse_case("ep", 1e8, axial_steps=40, control="path"), "t.toml"))
        us = []
        run_stages(built.model, built.stages, linear.make_solver("pardiso"), NewtonOptions(), SteppingOptions(),
                   lambda info: us.append(info.u.copy()))
        maps = open("/proc/self/maps").read()
        print(len(us), hashlib.sha1(np.concatenate(us).tobytes()).hexdigest(), "mkl_gnu_thread" in maps)
    """
    outs = [subprocess.run([sys.executable, "-c", code, mode], capture_output=True, text=True, check=True,
                           timeout=300).stdout.split() for mode in ("fresh", "threads first")]
    assert int(outs[0][0]) > 20 and outs[0] == outs[1]


@needs_pardiso
def test_threaded_pardiso_runs_in_mkl_reproducible_mode():
    """PARDISO on its threads factorizes the same matrix to different last bits from call to call
    unless MKL runs in its conditional numerical reproducibility mode, which rockfrac turns on before
    MKL loads (linear._choose_mkl_reproducibility: MKL_CBWR=AUTO) and a user's own choice overrides."""
    code = """if True:
        import numpy as np, scipy.sparse as sp
        from rockfrac.solve import linear
        s = linear.make_solver("pardiso").first  # PARDISO itself (make_solver checks its solves)
        s.begin_step()
        a = sp.diags([-1.0, 2.5, -1.0], [-1, 0, 1], shape=(3000, 3000), format="csr")
        s.factorize(a).solve(np.ones(3000))
        print(s._solver.libmkl.MKL_CBWR_Get(1))  # the branch: 1 off, 2 AUTO, 3 COMPATIBLE
    """
    env = {k: v for k, v in os.environ.items() if k != "MKL_CBWR"}
    branch = [subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=120,
                             env=dict(env, **extra)).stdout.split()[-1] for extra in ({}, {"MKL_CBWR": "COMPATIBLE"})]
    assert branch == ["2", "3"]
