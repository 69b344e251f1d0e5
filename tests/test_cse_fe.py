"""EP and RP cohesive surfaces in the paper's specimen, against closed forms of the discrete problem."""

import numpy as np
import pytest
from conftest import E, H, NU, P, THETA, TABLE1, W, paper_case, with_law

from rockfrac import analytic

MC_FORCE = analytic.mohr_coulomb_force(P, THETA, TABLE1["c_p"], np.tan(TABLE1["phi_p"]), W)


def axial(h):
    return h["stage"] == "axial"


def test_mohr_coulomb_force_is_the_reconstructed_3700_N_per_m():
    assert MC_FORCE == pytest.approx(3681.2, abs=0.5)  # the paper: about 3700 N/m
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


@pytest.mark.parametrize("gf", [1e4, 10.0])
def test_residual_force_tends_to_confinement_times_width(run, gf):
    """F = W q(chi, c, tan phi) at every plastic step, and F -> p W as the strengths vanish.

    On the yield surface the slip work rate is c |du_t^p| (Carol), so c decays like
    c_p / (1 + alpha_c c_p u / G_f^II): with Table 1's G_f = 1e4 J/m^2 the residual is approached
    only slowly; with G_f = 10 J/m^2 the strengths vanish within the run (after a snap-back).
    """
    case = with_law(paper_case("rp", axial_displacement=0.02, axial_steps=400, control="path",
                               path_increment=1e-4), GfI=gf, GfII=gf)
    h, _, s = run(case)
    assert s.result.completed and h["u_axial"][-1] == pytest.approx(0.02, rel=1e-12)
    assert analytic.strength_force(P, THETA, 0.0, 0.0, 0.0, W) == pytest.approx(P * W)
    pl = h["n_plastic"] > 0
    f = h["F_axial"][pl]
    assert np.all(np.diff(f) < 0) and np.all(f > P * W)
    allowed = [analytic.strength_force(P, THETA, chi, c, tp, W)
               for chi, c, tp in zip(h["chi"][pl], h["c"][pl], h["tan_phi"][pl])]
    np.testing.assert_allclose(f, allowed, rtol=1e-7)
    c_hyperbolic = TABLE1["c_p"] / (1 + TABLE1["alpha_c"] * TABLE1["c_p"] * np.abs(h["jump_p_norm"][pl]) / gf)
    assert h["c"][pl][-1] == pytest.approx(c_hyperbolic[-1], rel=0.1)
    if gf == 10.0:
        assert f[-1] < 1.02 * P * W  # strengths gone: confinement x width
        # the snap-back was traced: the axial displacement goes back under path control (from the last
        # load step on: with the RP return rescued, the first path step may cross the whole snap-back)
        path = np.flatnonzero(h["control"] == "path")
        assert np.any(np.diff(h["u_axial"][path[0] - 1:]) < 0)
    else:
        assert 1.2 * P * W < f[-1] < 0.3 * h["F_axial"].max()  # far into softening, residual not yet reached


def test_rp_converged_steps_solve_the_papers_local_problem(run):
    """The augmented return converges to eq. (34): for each plastic step's jump increment the
    local problem (34) returns the same traction and ISVs, and the surface stays rigid."""
    from rockfrac.laws import cohesive as law
    from rockfrac.laws.cohesive_params import N_STATE, S_EPSN, S_EPSS, S_TN, S_TT, S_UPN, S_UPT, CohesiveLaw

    _, pts, _ = run(paper_case("rp", axial_displacement=1.5e-3, axial_steps=60))
    p = CohesiveLaw(**TABLE1).as_array()
    checked = 0
    for point in (0, 1):
        rows = np.flatnonzero(pts["point"] == point)
        for prev, cur in zip(rows, rows[1:]):
            if pts["state"][cur] != "plastic" or pts["state"][prev] != "plastic":
                continue
            jump = np.array([pts["jump_t"][cur], pts["jump_n"][cur]])
            # rigid: no elastic jump beyond the solver tolerance, a millionth of a 1e9 Pa/m penalty's
            gap = np.abs(jump - [pts["jump_p_t"][cur], pts["jump_p_n"][cur]]).max()
            assert gap < 1e-6 * TABLE1["c_p"] / 1e9
            s_old = np.zeros(N_STATE)
            for slot, col in ((S_TT, "T_t"), (S_TN, "T_n"), (S_UPT, "jump_p_t"), (S_UPN, "jump_p_n"),
                              (S_EPSN, "eps_n_p"), (S_EPSS, "eps_s_p")):
                s_old[slot] = pts[col][prev]
            du = jump - [pts["jump_t"][prev], pts["jump_n"][prev]]
            guess = np.array([pts["T_t"][prev], pts["T_n"][prev], s_old[S_EPSN], s_old[S_EPSS], 0.0])
            s_new, d = np.zeros(N_STATE), np.zeros((2, 2))
            assert law.rp_update(du, s_old, p, guess, s_new, d) == 1
            np.testing.assert_allclose(s_new[[S_TT, S_TN]], [pts["T_t"][cur], pts["T_n"][cur]], rtol=1e-7)
            np.testing.assert_allclose(s_new[[S_EPSN, S_EPSS]], [pts["eps_n_p"][cur], pts["eps_s_p"][cur]],
                                       rtol=1e-7)
            checked += 1
    assert checked > 50


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
