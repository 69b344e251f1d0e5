"""EP and RP cohesive surfaces in the paper's specimen, against closed forms of the discrete problem."""

import numpy as np
import pytest
from conftest import E, H, NU, P, THETA, TABLE1, W, paper_case, with_law

from rockfrac import analytic

MC_FORCE = analytic.mohr_coulomb_force(P, THETA, TABLE1["c_p"], np.tan(TABLE1["phi_p"]), W)


def axial(h):
    return h["stage"] == "axial"


def test_mohr_coulomb_force_is_the_reconstructed_3700_N_per_m():
    assert MC_FORCE == pytest.approx(3654.4, abs=0.5)
    # the capped hyperbola of Table 1 degenerates to the cone: same activation force
    chi_p = TABLE1["c_p"] / np.tan(TABLE1["phi_p"])
    assert analytic.strength_force(P, THETA, chi_p, TABLE1["c_p"], np.tan(TABLE1["phi_p"]), W) == pytest.approx(
        MC_FORCE, rel=2e-4)  # chi_p = 15680 is c_p cot(phi_p) to 4 digits


def test_rp_is_the_uncracked_elastic_curve_until_activation(run):
    h, pts, _ = run(paper_case("rp", axial_displacement=4.2e-4, axial_steps=420))
    pre = h["n_plastic"] == 0
    expected = np.array([analytic.elastic_force(u, P * (1 if s == "axial" else lf), E, NU, W, H)
                         for u, s, lf in zip(h["u_axial"], h["stage"], h["load_factor"])])
    np.testing.assert_allclose(h["F_axial"][pre], expected[pre], rtol=1e-10)
    # the constrained surface does not move at all
    rows = pts["state"] == "constrained"
    assert np.abs(pts["jump_t"][rows]).max() < 1e-16 and np.abs(pts["jump_n"][rows]).max() < 1e-16
    # activation: the last constrained step is just below the Mohr-Coulomb load (steps of
    # ~8 N/m) and the elastic prediction of the first plastic step above it
    first = np.flatnonzero(~pre)[0]
    assert MC_FORCE - 10.0 < h["F_axial"][first - 1] <= MC_FORCE
    assert analytic.elastic_force(h["u_axial"][first], P, E, NU, W, H) > MC_FORCE


@pytest.mark.parametrize("k", [1e8, 1e9])
def test_ep_pre_peak_slope_is_the_series_compliance(run, k):
    h, _, _ = run(paper_case("ep", k, axial_displacement=3e-4, axial_steps=6))
    a = axial(h) & (h["n_plastic"] == 0)
    slope = np.diff(h["F_axial"][a]) / np.diff(h["u_axial"][a])
    expected = analytic.series_slope(E, NU, W, H, k, k, THETA)
    np.testing.assert_allclose(slope, expected, rtol=1e-9)
    assert expected < 0.95 * analytic.series_slope(E, NU, W, H, 1e30, 1e30, THETA)


def test_softening_force_is_what_the_current_strengths_allow(run):
    """At every plastic step F_axial = W q with F(T(q); chi, c, tan phi) = 0 (exact, homogeneous)."""
    for form, k in (("rp", None), ("ep", 1e9)):
        h, _, _ = run(paper_case(form, k, axial_displacement=3e-3, axial_steps=100), form)
        plastic = np.flatnonzero(h["n_plastic"] > 0)
        assert plastic.size > 50
        allowed = [analytic.strength_force(P, THETA, chi, c, tp, W)
                   for chi, c, tp in zip(h["chi"][plastic], h["c"][plastic], h["tan_phi"][plastic])]
        np.testing.assert_allclose(h["F_axial"][plastic], allowed, rtol=1e-7)
        assert h["F_axial"][-1] < 0.6 * h["F_axial"].max()  # deep in the softening branch
        assert np.all(np.diff(h["F_axial"][plastic]) < 0)


def test_residual_force_tends_to_confinement_times_width(run):
    h, _, _ = run(paper_case("rp", axial_displacement=0.1, axial_steps=400, control="path",
                             path_increment=5e-4))
    assert analytic.strength_force(P, THETA, 0.0, 0.0, 0.0, W) == pytest.approx(P * W)
    f = h["F_axial"][h["n_plastic"] > 0]
    assert np.all(np.diff(f) < 0)
    assert f[-1] < 1.25 * P * W and f[-1] > P * W


def test_ep_tends_to_rp_as_the_penalty_grows(run):
    """The softening force at the end of the stage converges to RP's as k grows (path control
    traces the snap-back the soft penalty causes at the peak)."""
    load = {"axial_displacement": 1.2e-3, "axial_steps": 120, "control": "path", "path_increment": 1e-5}
    h_rp, _, _ = run(paper_case("rp", **load), "rp")
    end_err = []
    for k in (1e8, 1e9, 1e10, 1e11):
        h, _, s = run(paper_case("ep", k, **load), f"ep{k:g}")
        assert s.result.completed and h["u_axial"][-1] == pytest.approx(1.2e-3, rel=1e-12)
        end_err.append(abs(h["F_axial"][-1] - h_rp["F_axial"][-1]) / h_rp["F_axial"].max())
    assert all(b < a for a, b in zip(end_err, end_err[1:])), end_err
    assert end_err[0] > 1e-2 and end_err[-1] < 2e-4


def test_ep_and_rp_isv_histories_coincide_versus_plastic_jump(run):
    h_rp, _, _ = run(paper_case("rp", axial_displacement=3e-3, axial_steps=150), "rp")
    h_ep, _, _ = run(paper_case("ep", 1e9, axial_displacement=3e-3, axial_steps=150), "ep")
    grid = np.linspace(5e-5, 2.5e-3, 40)
    for name, scale in (("c", TABLE1["c_p"]), ("tan_phi", np.tan(TABLE1["phi_p"])),
                        ("tan_psi", np.tan(TABLE1["psi_p"])), ("chi", TABLE1["chi_p"])):
        rp = np.interp(grid, h_rp["jump_p_norm"], h_rp[name])
        ep = np.interp(grid, h_ep["jump_p_norm"], h_ep[name])
        assert np.abs(rp - ep).max() < 5e-3 * scale, name
