"""Unloading and reloading of EP and RP surfaces; a clean stop that keeps the converged steps."""

import numpy as np
import pytest
from conftest import E, H, NU, THETA, W, paper_case

from rockfrac import analytic

BULK_SLOPE = W * analytic.plane_strain_modulus(E, NU) / H


def test_rp_unloads_to_the_constrained_state_and_reloads_rigidly(run):
    h, pts, s = run(paper_case("rp", axial_displacement=[6e-4, 4e-4, 7e-4], axial_steps=20))
    assert s.result.completed
    unload = h["stage"] == "axial 2"
    reload_ = h["stage"] == "axial 3"
    assert np.all(h["n_plastic"][unload] == 0)
    # rigid crack: unloading follows the uncracked elastic slope (to Newton's tolerance, 1e-8)
    u, f = h["u_axial"][unload], h["F_axial"][unload]
    np.testing.assert_allclose(np.diff(f) / np.diff(u), BULK_SLOPE, rtol=2e-8)
    # the jump is frozen while constrained
    last_plastic = int(h["step"][~unload & ~reload_][-1])
    frozen = pts["step"] == last_plastic
    for st in h["step"][unload]:
        rows = pts["step"] == st
        np.testing.assert_allclose(pts["jump_t"][rows], pts["jump_t"][frozen], rtol=0, atol=1e-15)
        np.testing.assert_allclose(pts["jump_n"][rows], pts["jump_n"][frozen], rtol=0, atol=1e-15)
        assert set(pts["state"][rows]) == {"constrained"}
    # on reloading it yields again where it left off: the strengths did not change while constrained
    again = np.flatnonzero(reload_ & (h["n_plastic"] > 0))[0]
    allowed = analytic.strength_force(2e4, THETA, h["chi"][again], h["c"][again], h["tan_phi"][again], W)
    assert h["F_axial"][again] == pytest.approx(allowed, rel=1e-7)
    assert h["F_axial"][again - 1] <= allowed * (1 + 1e-9)


def test_ep_unloads_elastically_with_the_series_slope(run):
    h, _, s = run(paper_case("ep", 1e9, axial_displacement=[6e-4, 4e-4], axial_steps=20))
    assert s.result.completed
    unload = h["stage"] == "axial 2"
    assert np.all(h["n_plastic"][unload] == 0)
    slope = np.diff(h["F_axial"][unload]) / np.diff(h["u_axial"][unload])
    np.testing.assert_allclose(slope, analytic.series_slope(E, NU, W, H, 1e9, 1e9, THETA), rtol=1e-9)


def test_a_failed_run_stops_cleanly_and_keeps_every_converged_step(run, tmp_path):
    """EP k = 1e8 with the unreduced rates snaps back at the peak: displacement control cannot pass
    it (the paper's non-convergence); the run stops with a message and keeps its history."""
    case = paper_case("ep", 1e8, axial_displacement=1.2e-3, axial_steps=120)
    case["solver"] = {"min_step": 1e-2, "max_iterations": 15}
    h, pts, s = run(case, "stop")
    assert not s.result.completed
    assert "min_step" in s.result.message
    assert len(h["step"]) == s.result.steps > 50
    assert h["u_axial"][-1] < 1.2e-3
    assert np.all(np.isfinite(h["F_axial"]))
    assert len(pts["step"]) == 2 * len(h["step"])
    log = (tmp_path / "stop" / "run.log").read_text()
    assert "cutting back" in log and "end: stopped" in log
    # path control gets past the same peak
    case["loading"]["control"] = "path"
    h2, _, s2 = run(case, "path")
    assert s2.result.completed and h2["u_axial"][-1] == pytest.approx(1.2e-3)
    assert np.any(np.diff(h2["u_axial"][h2["control"] == "path"]) < 0)  # the snap-back is traced
