"""The thread rule (rockfrac.threads): every item-parallel kernel is declared with
``parallel_kernel``; a call below its threshold runs the serial compilation on the calling thread
and never compiles the parallel one; from the threshold on it runs on Numba's threads; both give
the same bits."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import numba as nb
import numpy as np
import pytest

from rockfrac import threads

PACKAGE = Path(__file__).resolve().parents[1] / "src" / "rockfrac"


def _decorators(node: ast.FunctionDef) -> list[str]:
    return [ast.unparse(d) for d in node.decorator_list]


def test_every_prange_kernel_is_declared_through_the_rule():
    """No ``parallel=True`` outside rockfrac.threads, and every function with a ``prange`` loop is
    a ``parallel_kernel`` (a ``prange`` in a plain njit function would silently run serially)."""
    offenders = []
    for f in sorted(PACKAGE.rglob("*.py")):
        if f.name == "threads.py":
            continue
        tree = ast.parse(f.read_text())
        for node in ast.walk(tree):
            if isinstance(node, ast.keyword) and node.arg == "parallel":
                offenders.append(f"{f.name}:{node.value.lineno} parallel=...")
            if isinstance(node, ast.FunctionDef):
                uses_prange = any(isinstance(n, ast.Attribute) and n.attr == "prange" for n in ast.walk(node))
                if uses_prange and not any(d.startswith("parallel_kernel(") for d in _decorators(node)):
                    offenders.append(f"{f.name}:{node.lineno} {node.name} has a prange but no parallel_kernel")
    assert not offenders, offenders


def test_the_package_kernels_are_registered_with_a_positive_threshold():
    import rockfrac.elements.ede
    import rockfrac.elements.plastic_solid
    import rockfrac.laws.bifurcation
    import rockfrac.laws.bilinear
    import rockfrac.laws.drive  # noqa: F401

    names = {k.__qualname__ for k in threads.KERNELS}
    assert {"ep_points", "rp_points", "dp_blocks", "ede_blocks", "flow_points", "strengths_points", "gradients",
            "strains", "screen_plane_strain", "minima_plane_strain"} <= names
    for k in threads.KERNELS:
        assert k.below == max(1, int(threads.SERIAL_WORK / k.cost)) and k.below >= 1
        assert k.serial.py_func.__qualname__ == k.__qualname__ + "__serial"  # a cache key of its own


def _fill(out):
    for i in nb.prange(out.shape[0]):
        out[i] = nb.get_thread_id()


# Not cached: a cached function calling nb.get_thread_id() outside a parallel region, loaded from the
# cache before Numba's threading layer has started, crashes the process (a Numba limitation; no
# package kernel calls it)
def fill_kernel() -> threads.ParallelKernel:
    return threads.ParallelKernel(_fill, cost=1e-3, items_arg=0, cache=False)  # 4 ms: serial below 4 items


def test_below_the_threshold_the_parallel_version_is_never_compiled():
    kernel = fill_kernel()
    assert kernel.below == 4
    out = np.full(3, -1, dtype=np.int64)
    kernel(out)
    assert set(out) == {0}  # the calling thread did every item
    assert kernel.serial.signatures and not kernel.parallel.signatures
    if nb.get_num_threads() < 2:
        pytest.skip("one Numba thread only")
    big = np.full(4000, -1, dtype=np.int64)  # >= 4 items: the prange version, on the threads
    kernel(big)
    assert kernel.parallel.signatures and len(set(big)) == nb.get_num_threads()


def test_force_overrides_the_rule(monkeypatch):
    kernel = fill_kernel()
    monkeypatch.setattr(threads, "FORCE", "serial")
    assert kernel.path(10**9) == "serial"
    monkeypatch.setattr(threads, "FORCE", "parallel")
    assert kernel.path(1) == "parallel"
    monkeypatch.setattr(threads, "FORCE", None)
    assert kernel.path(3) == "serial" and kernel.path(4) == "parallel"
    with pytest.raises(ValueError, match="cost per item"):
        threads.parallel_kernel(cost=0.0)


def test_serial_and_parallel_versions_give_the_same_bits():
    """The cohesive law's EP points and strengths at 3000 points, both compilations, same bits."""
    from rockfrac.laws.cohesive_params import N_STATE, S_EPSN, S_EPSS, CohesiveLaw
    from rockfrac.laws.cohesive_surface import strengths_points
    from rockfrac.laws.mohr_coulomb_surface import ep_points

    rng = np.random.default_rng(3)
    law = CohesiveLaw(GfI=1e4, GfII=1e4, chi_p=15680.0, chi_r=0.0, c_p=9053.0, c_r=0.0, phi_p=0.5236,
                      phi_r=0.0, psi_p=0.087, alpha_chi=2e3, alpha_c=2e3, alpha_phi=9e2, alpha_psi=9e2,
                      kn=1e9, kt=1e9, work_rule="trapezoidal")
    p = law.as_array()
    n = 3000
    ang = rng.uniform(0, np.pi, n)
    frame = np.empty((n, 2, 2))
    frame[:, 0, 0], frame[:, 0, 1], frame[:, 1, 0], frame[:, 1, 1] = np.cos(ang), np.sin(ang), -np.sin(ang), np.cos(ang)
    weight = rng.uniform(0.5e-3, 1.5e-3, n)
    djump = rng.uniform(-3e-5, 3e-5, (n, 2))
    s_old = np.zeros((n, N_STATE))
    d_old = rng.uniform(size=(n, 2, 2))
    outs = {}
    for path in ("serial", "parallel"):
        s_new, d_new = np.zeros_like(s_old), np.zeros_like(d_old)
        fe, ke, status = np.zeros((n, 4)), np.zeros((n, 4, 4)), np.zeros(n, dtype=np.int64)
        getattr(ep_points, path)(frame, weight, djump, s_old, d_old, p, s_new, d_new, fe, ke, status)
        q = getattr(strengths_points, path)(np.ascontiguousarray(s_new[:, S_EPSN]),
                                            np.ascontiguousarray(s_new[:, S_EPSS]), p)
        outs[path] = [s_new, d_new, fe, ke, status, q]
    assert 100 < np.sum(outs["serial"][4] == 1) < n - 100  # plastic and elastic points both
    for a, b in zip(outs["serial"], outs["parallel"]):
        assert np.array_equal(a, b, equal_nan=True)


def test_small_runs_never_compile_a_parallel_kernel(tmp_path):
    """The paper's sizes (a CSE case and an EDE case) stay below every threshold: in a fresh
    process no kernel's parallel version gets a signature (it is neither compiled nor loaded)."""
    code = """if True:
        from rockfrac import threads
        from rockfrac.case.build import build
        from rockfrac.case.schema import parse_case
        from rockfrac.solve import linear
        from rockfrac.solve.newton import NewtonOptions
        from rockfrac.solve.stepping import SteppingOptions, run_stages
        from rockfrac.studies import table1
        for case in (table1.cse_case("ep", 1e9, axial_steps=20), table1.ede_case(axial_steps=30)):
            built = build(parse_case(case, "t.toml"))
            run_stages(built.model, built.stages, linear.make_solver("auto"), NewtonOptions(), SteppingOptions(),
                       lambda info: None)
        used = sorted(k.__qualname__ for k in threads.KERNELS if k.serial.signatures)
        parallel = sorted(k.__qualname__ for k in threads.KERNELS if k.parallel.signatures)
        print(" ".join(used) + "|" + " ".join(parallel))
    """
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=600)
    used, parallel = out.stdout.strip().split("|")
    assert {"ep_points", "ede_blocks", "gradients"} <= set(used.split())
    assert parallel == ""
