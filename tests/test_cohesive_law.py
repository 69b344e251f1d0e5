"""Cohesive traction law of Sect. 4.2 (tension-capped hyperbolic Mohr-Coulomb) and its drivers.

Checks the EP return map (eq. 31), the RP local problem (eq. 34), their consistent tangents
against finite differences, closed forms along pure opening, the degenerate corner of Table 1,
EP -> RP as k -> infinity, and the material-point driver.
"""

import dataclasses
import math

import numpy as np
import pytest

from rockfrac.laws import cohesive as law
from rockfrac.laws.cohesive_params import (
    N_STATE,
    P_CN,
    P_CT,
    S_DGAMMA,
    S_EPSN,
    S_EPSS,
    S_MODE,
    S_TN,
    S_TT,
    S_UPN,
    S_UPT,
    CohesiveLaw,
)
from rockfrac.laws.drive import drive_path

# Table 1, CSE columns (SI, radians); EP variant with k = 1e9 Pa/m
TABLE1 = dict(GfI=1.0e4, GfII=1.0e4, chi_p=15680.0, chi_r=0.0, c_p=9053.0, c_r=0.0,
              phi_p=0.5236, phi_r=0.0, psi_p=0.087, alpha_chi=2.0e3, alpha_c=2.0e3,
              alpha_phi=9.0e2, alpha_psi=9.0e2)
EP = CohesiveLaw(**TABLE1, kn=1.0e9, kt=1.0e9)
RP = CohesiveLaw(**TABLE1)
C_P = TABLE1["c_p"]
S_REF = TABLE1["c_p"] + TABLE1["chi_p"]


def state(tt=0.0, tn=0.0, eps_n=0.0, eps_s=0.0):
    """A committed state vector with the given traction [Pa] and ISVs."""
    s = np.zeros(N_STATE)
    s[S_TT], s[S_TN], s[S_EPSN], s[S_EPSS] = tt, tn, eps_n, eps_s
    return s


def ep(du, s_old, p):
    """One EP update: (status, new state, tangent)."""
    s_new = np.zeros(N_STATE)
    d = np.zeros((2, 2))
    st = law.ep_update(np.asarray(du, dtype=float), s_old, p, s_new, d)
    return st, s_new, d


def rp(du, s_old, p, x_guess):
    """One RP update: (status, new state, tangent)."""
    s_new = np.zeros(N_STATE)
    d = np.zeros((2, 2))
    st = law.rp_update(np.asarray(du, dtype=float), s_old, p, x_guess, s_new, d)
    return st, s_new, d


def fd_tangent(update, du, h):
    """Central finite differences of T(du) [Pa/m]."""
    d = np.zeros((2, 2))
    for j in range(2):
        e = np.zeros(2)
        e[j] = h
        sp, sm = update(np.asarray(du) + e), update(np.asarray(du) - e)
        d[:, j] = (sp[S_TT:S_TN + 1] - sm[S_TT:S_TN + 1]) / (2.0 * h)
    return d


def yield_at(s, p):
    """F [Pa] at the traction and ISVs of a state vector."""
    return law.yield_function(s[S_TT], s[S_TN], s[S_EPSN], s[S_EPSS], p)


def rel_err(a, b):
    """Frobenius relative error of a against the reference b."""
    return np.linalg.norm(a - b) / np.linalg.norm(b)


# --- EP return map ------------------------------------------------------------------------


def test_elastic_step_is_exact():
    p = EP.as_array()
    s_old = state(100.0, -2000.0, 1e-5, 2e-5)
    du = np.array([1e-7, -1e-7])
    st, s_new, d = ep(du, s_old, p)
    assert st == 0
    k = 1.0 / p[[P_CT, P_CN]]  # the parameter vector stores the compliance
    np.testing.assert_array_equal(s_new[[S_TT, S_TN]], s_old[[S_TT, S_TN]] + k * du)
    np.testing.assert_array_equal(d, np.diag(k))
    np.testing.assert_allclose(s_new[[S_TT, S_TN]], [200.0, -2100.0], rtol=1e-15)
    assert s_new[S_MODE] == 0.0 and s_new[S_DGAMMA] == 0.0
    np.testing.assert_array_equal(s_new[[S_UPT, S_UPN, S_EPSN, S_EPSS]], s_old[[S_UPT, S_UPN, S_EPSN, S_EPSS]])


# (state, du, law variant): elastic; compression-shear from a softened state; tension with a
# little shear next to the corner (Table 1 and exactly degenerate a_F = 0); mixed tension-shear
DEGENERATE = dataclasses.replace(EP, chi_p=TABLE1["c_p"] / math.tan(TABLE1["phi_p"]))
UNEQUAL_GF = dataclasses.replace(EP, GfI=0.5e4, GfII=3.0e4)  # tells Carol's pairing from the paper's
EP_CASES = {
    "elastic": (state(100.0, -2000.0), [1e-7, -1e-7], EP),
    "compression-shear softened": (state(1.0e4, -2.0e4, 0.0, 5e-4), [2e-6, 0.0], EP),
    "tension-shear near corner": (state(), [1e-7, 1.6e-5], EP),
    "tension-shear exact corner": (state(), [-1e-7, 1.6e-5], DEGENERATE),
    "mixed tension-shear": (state(5000.0, 2000.0, 1e-4, 1e-4), [3e-6, 2e-6], UNEQUAL_GF),
}


@pytest.mark.parametrize("name", list(EP_CASES))
def test_ep_consistent_tangent_matches_finite_differences(name):
    s_old, du, variant = EP_CASES[name]
    p = variant.as_array()
    st, _, d = ep(du, s_old, p)
    assert st == (0 if name == "elastic" else 1)
    d_fd = fd_tangent(lambda u: ep(u, s_old, p)[1], du, h=5e-11)  # T changes by ~0.05 Pa
    assert rel_err(d, d_fd) < 1e-6


@pytest.mark.parametrize("name", [n for n in EP_CASES if n != "elastic"])
def test_ep_return_map_is_consistent(name):
    """F(T, q) = 0, du - C dT = dgamma g(T, q) = du^p, backward-Euler ISV increments (Carol's pairing)."""
    s_old, du, variant = EP_CASES[name]
    p = variant.as_array()
    st, s, _ = ep(du, s_old, p)
    assert st == 1 and s[S_MODE] == 1.0 and s[S_DGAMMA] > 0.0
    assert abs(yield_at(s, p)) < 1e-8 * C_P
    dup = s[[S_UPT, S_UPN]] - s_old[[S_UPT, S_UPN]]
    gt, gn = law.flow_direction(s[S_TT], s[S_TN], s[S_EPSN], s[S_EPSS], p)
    np.testing.assert_allclose(dup, s[S_DGAMMA] * np.array([gt, gn]), rtol=1e-14, atol=0)
    elastic = (s[[S_TT, S_TN]] - s_old[[S_TT, S_TN]]) / np.array([variant.kt, variant.kn])
    np.testing.assert_allclose(np.asarray(du) - elastic, dup, rtol=1e-9, atol=1e-12 * np.abs(du).max())
    tphi = law.strengths(s[S_EPSN], s[S_EPSS], p)[2]
    de_n = max(s[S_TN], 0.0) * dup[1] / variant.GfI
    de_s = max(abs(s[S_TT]) + min(s[S_TN], 0.0) * tphi, 0.0) * abs(dup[0]) / variant.GfII
    np.testing.assert_allclose(s[S_EPSN] - s_old[S_EPSN], de_n, rtol=1e-9, atol=1e-18)
    np.testing.assert_allclose(s[S_EPSS] - s_old[S_EPSS], de_s, rtol=1e-9, atol=1e-18)


@pytest.mark.parametrize("ws", [(0.0, 0.0, 0.0), (0.5, 1500.0, 2200.0)], ids=["backward-euler", "trapezoidal"])
def test_local_jacobian_matches_finite_differences(ws):
    """Analytic J of the local problem, every partial (ISVs, brackets, |.|), EP and RP forms, both work rules."""
    p = UNEQUAL_GF.as_array()
    ws = np.array(ws)
    du, t_old = np.array([2e-6, 1e-6]), np.array([3000.0, -1000.0])
    points = [
        np.array([4000.0, -6000.0, 1e-4, 3e-4, 2e-6]),  # compression-shear: eps_s row active
        np.array([-2500.0, 3000.0, 2e-4, 1e-4, 3e-6]),  # tension, T_t < 0: both ISV rows active
    ]
    for comp in (np.array([1e-9, 1e-9]), np.zeros(2)):
        for x in points:
            r, jac = np.zeros(5), np.zeros((5, 5))
            law._system(x, du, t_old, 5e-5, 5e-5, comp, 1e5, p, ws, r, jac)
            jac_fd = np.zeros((5, 5))
            for j in range(5):
                h = 1e-6 * abs(x[j])
                rp_, rm_ = np.zeros(5), np.zeros(5)
                xp, xm = x.copy(), x.copy()
                xp[j] += h
                xm[j] -= h
                law._system(xp, du, t_old, 5e-5, 5e-5, comp, 1e5, p, ws, rp_, np.zeros((5, 5)))
                law._system(xm, du, t_old, 5e-5, 5e-5, comp, 1e5, p, ws, rm_, np.zeros((5, 5)))
                jac_fd[:, j] = (rp_ - rm_) / (2 * h)
            scale = np.abs(jac).max(axis=1, keepdims=True)
            np.testing.assert_allclose(jac / scale, jac_fd / scale, rtol=0, atol=1e-7)


def test_points_driver_matches_single_point_updates():
    p = EP.as_array()
    du = np.array([[1e-7, -1e-7], [2e-6, 0.0], [1e-7, 1.6e-5], [3e-6, 2e-6]])
    s_old = np.array([state(100.0, -2000.0), state(1e4, -2e4, 0.0, 5e-4), state(),
                      state(5000.0, 2000.0, 1e-4, 1e-4)])
    s_new, d, status = np.zeros_like(s_old), np.zeros((4, 2, 2)), np.zeros(4, dtype=np.int64)
    law.ep_update_points(du, s_old, p, s_new, d, status)
    np.testing.assert_array_equal(status, [0, 1, 1, 1])
    for i in range(4):
        st, s1, d1 = ep(du[i], s_old[i], p)
        assert st == status[i]
        np.testing.assert_array_equal(s1, s_new[i])
        np.testing.assert_array_equal(d1, d[i])


# --- closed forms and the corner -------------------------------------------------------------


def opening_run(variant, n_steps, u_max=1e-3):
    """Pure opening: load elastically to chi_p, then n_steps equal steps to u_max [m]."""
    u_yield = variant.chi_p / variant.kn
    un = np.concatenate([[u_yield], u_yield + np.linspace(0.0, u_max, n_steps + 1)[1:]])
    return drive_path(variant, np.column_stack([np.zeros_like(un), un]))


def test_pure_opening_matches_closed_form_to_first_order():
    """chi_r = c_r = 0, alpha_chi = alpha_c = a, c_p > chi_p tan(phi_p): T_n = chi_p / (1 + a chi_p u_n^p / G_f^I)."""
    chi_p, a = 15680.0, 2.0e3
    variant = dataclasses.replace(UNEQUAL_GF, c_p=2.0 * chi_p * math.tan(TABLE1["phi_p"]))
    errors = []
    for n in (40, 80, 160):
        r = opening_run(variant, n)
        assert np.all(r["T_t"] == 0.0) and np.all(r["jump_p_t"] == 0.0) and np.all(r["eps_s_p"] == 0.0)
        exact = chi_p / (1.0 + a * chi_p * r["jump_p_n"] / variant.GfI)
        np.testing.assert_allclose(r["T_n"], r["chi"], rtol=0, atol=1e-10 * S_REF)  # the vertex
        errors.append(np.abs(r["T_n"] - exact).max())
    assert r["T_n"][-1] < 0.3 * chi_p  # well into softening
    assert errors[0] < 0.03 * chi_p
    for coarse, fine in zip(errors, errors[1:]):
        assert 1.8 < coarse / fine < 2.2  # backward Euler: first order


@pytest.mark.parametrize("variant", [EP, DEGENERATE], ids=["table1", "exact-cot"])
@pytest.mark.parametrize("shear", [0.0, 0.01, 0.1])
def test_degenerate_corner_opening_converges(variant, shear):
    """Table 1 puts the initial yield surface on its apex (a_F = c - chi tan(phi) ~ 0)."""
    p = variant.as_array()
    un = np.linspace(0.0, 5e-4, 101)[1:]
    r = drive_path(variant, np.column_stack([shear * un, un]))
    plastic = r["jump_p_n"] > 0.0
    assert plastic.sum() > 90
    f = np.array([law.yield_function(*row, p) for row in
                  zip(r["T_t"], r["T_n"], r["eps_n_p"], r["eps_s_p"])])
    assert np.abs(f[plastic]).max() < 1e-8 * C_P
    assert np.all(r["T_n"][plastic] <= r["chi"][plastic] * (1 + 1e-12))
    if shear == 0.0:
        assert np.all(r["T_t"] == 0.0)
        exact = variant.chi_p / (1.0 + 2e3 * variant.chi_p * r["jump_p_n"] / variant.GfI)
        np.testing.assert_allclose(r["T_n"][plastic], exact[plastic], rtol=0.01)
    else:
        assert np.all(r["T_t"][plastic] > 0.0) and np.all(r["eps_s_p"][plastic] > 0.0)


def test_return_from_trial_states_around_the_corner():
    """Trial tractions just past the apex, T_t^tr from 0 to 1 kPa either side: F = 0, sign kept."""
    for variant in (EP, DEGENERATE):
        p = variant.as_array()
        for tt in (0.0, 1e-6, -1e-3, 0.1, -1.0, 10.0, 1000.0):
            for tn in (15700.0, 16000.0, 20000.0, 40000.0):
                st, s, d = ep([tt / 1e9, tn / 1e9], state(), p)
                assert st == 1
                assert abs(yield_at(s, p)) < 1e-8 * C_P
                assert np.sign(s[S_TT]) == np.sign(tt) and abs(s[S_TT]) <= abs(tt)
                assert np.all(np.isfinite(d))


def test_cone_compression_shear_follows_yield_surface_and_softening():
    """Confined slip under Table 1: F = 0, eps_n = 0, c = c_p exp(-alpha_c eps_s), eq. for eps_s."""
    p = EP.as_array()
    un = -2e-5  # T_n = -20 kPa before slip
    ut = np.linspace(0.0, 3e-4, 151)
    r = drive_path(EP, np.column_stack([ut, np.full_like(ut, un)]))
    plastic = r["jump_p_t"] > 0.0
    assert plastic.sum() > 130
    f = np.array([law.yield_function(*row, p) for row in
                  zip(r["T_t"], r["T_n"], r["eps_n_p"], r["eps_s_p"])])
    assert np.abs(f[plastic]).max() < 1e-8 * C_P
    assert np.all(r["T_n"] < 0.0) and np.all(r["eps_n_p"] == 0.0)
    np.testing.assert_allclose(r["c"], C_P * np.exp(-2e3 * r["eps_s_p"]), rtol=1e-13)
    np.testing.assert_allclose(r["tan_phi"], math.tan(0.5236) * np.exp(-9e2 * r["eps_s_p"]), rtol=1e-13)
    # backward Euler of eps_s' = (|T_t| + T_n tan(phi)) |u_t^p'| / G_f^II, values at n+1
    de = np.diff(r["eps_s_p"])
    expect = (np.abs(r["T_t"][1:]) + r["T_n"][1:] * r["tan_phi"][1:]) * np.diff(r["jump_p_t"]) / 1e4
    np.testing.assert_allclose(de, expect, rtol=1e-9, atol=1e-16)
    assert r["c"][-1] < 0.7 * C_P and np.all(np.diff(r["c"]) <= 0.0)


# --- RP local problem -------------------------------------------------------------------------


RP_CASES = {
    "compression-shear": (state(), [1e-5, 1e-6]),
    "tension-shear": (state(), [1e-6, 2e-6]),
    "softened, T_t < 0": (state(0.0, 0.0, 1e-4, 3e-4), [-4e-6, 1e-6]),
}


@pytest.mark.parametrize("name", list(RP_CASES))
def test_rp_consistent_tangent_matches_finite_differences(name):
    s_old, du = RP_CASES[name]
    p = RP.as_array()
    guess = np.array([0.0, 0.0, s_old[S_EPSN], s_old[S_EPSS], 0.0])
    st, s, d = rp(du, s_old, p, guess)
    assert st == 1 and s[S_MODE] == 1.0
    assert abs(yield_at(s, p)) < 1e-8 * C_P
    np.testing.assert_array_equal(s[[S_UPT, S_UPN]], du)
    gt, gn = law.flow_direction(s[S_TT], s[S_TN], s[S_EPSN], s[S_EPSS], p)
    np.testing.assert_allclose(s[S_DGAMMA] * np.array([gt, gn]), du, rtol=1e-9)
    h = 1e-5 * np.abs(du)[np.nonzero(du)].min()  # T(du) is sensitive to the direction of du
    d_fd = fd_tangent(lambda u: rp(u, s_old, p, guess)[1], du, h)
    assert rel_err(d, d_fd) < 1e-6
    x = np.array([s[S_TT], s[S_TN], s[S_EPSN], s[S_EPSS], s[S_DGAMMA]])
    d_at = np.zeros((2, 2))
    assert law.rp_tangent_at(x, np.asarray(du, float), s_old, p, d_at) == 0
    np.testing.assert_allclose(d_at, d, rtol=1e-12)


@pytest.mark.parametrize("du", [[0.0, -1e-6], [1e-6, 0.0], [-1e-6, -1e-7], [0.0, 0.0]])
def test_rp_inadmissible_direction_unloads(du):
    """g_n = tan(psi) > 0: closing or non-dilatant slip is not a plastic direction -> status -2."""
    p = RP.as_array()
    st, s, _ = rp(du, state(), p, np.array([1e4, -5e3, 0.0, 0.0, 1e-6]))
    assert st == -2
    np.testing.assert_array_equal(s, state())


def test_augmented_return_is_the_ep_return_with_stiffness_r():
    """The RP element's return (K^e = r I, T_old = lambda) solves eq. (31) with kn = kt = r."""
    p = RP.as_array()
    r = 4.0e8
    lam = np.array([6000.0, -1.0e4])
    s_old = state(lam[0], lam[1], 1e-5, 2e-5)
    h = np.array([2e-5, 1e-6])
    s_new, d = np.zeros(N_STATE), np.zeros((2, 2))
    assert law.return_map(h, s_old, np.array([1 / r, 1 / r]), p, s_new, d) == 1
    st, s_ep, d_ep = ep(h, s_old, dataclasses.replace(RP, kn=r, kt=r).as_array())
    assert st == 1
    np.testing.assert_array_equal(s_new, s_ep)
    np.testing.assert_array_equal(d, d_ep)
    assert abs(yield_at(s_new, p)) < 1e-8 * C_P
    gt, gn = law.flow_direction(s_new[S_TT], s_new[S_TN], s_new[S_EPSN], s_new[S_EPSS], p)
    np.testing.assert_allclose(s_new[[S_TT, S_TN]], lam + r * h - r * s_new[S_DGAMMA] * np.array([gt, gn]),
                               rtol=1e-10)


def rp_path(increments, p):
    """RP along plastic-jump increments (n, 2), each solve starting from the previous solution."""
    s = state()
    x = np.zeros(5)
    out = []
    for du in increments:
        st, s_new, _ = rp(du, s, p, x)
        assert st == 1
        s = s_new
        x = np.array([s[S_TT], s[S_TN], s[S_EPSN], s[S_EPSS], s[S_DGAMMA]])
        out.append(s)
    return np.array(out)


def test_rp_reproduces_ep_given_its_plastic_increments():
    """Eq. (34) with du = EP's du^p is EP's eq. (31): same T and eps (the unified kernel)."""
    p = RP.as_array()
    ut = np.linspace(0.0, 2e-4, 41)[1:]
    r = drive_path(EP, np.column_stack([ut, 0.2 * ut]))
    up = np.column_stack([r["jump_p_t"], r["jump_p_n"]])
    first = np.argmax(np.abs(up).sum(axis=1) > 0)
    inc = np.diff(up[first - 1:], axis=0)
    out = rp_path(inc, p)
    np.testing.assert_allclose(out[:, S_TT], r["T_t"][first:], rtol=1e-7)
    np.testing.assert_allclose(out[:, S_TN], r["T_n"][first:], rtol=1e-7)
    np.testing.assert_allclose(out[:, S_EPSN], r["eps_n_p"][first:], rtol=1e-7)
    np.testing.assert_allclose(out[:, S_EPSS], r["eps_s_p"][first:], rtol=1e-7)


def test_ep_tends_to_rp_as_stiffness_grows():
    """Same total jump path: EP(k) - RP = O(1/k); at k = 1e13 the difference is negligible."""
    p = RP.as_array()
    step = np.array([1e-5, 1.5e-6])  # admissible: du_n / |du_t| > tan(psi)
    path = np.outer(np.arange(1, 21), step)
    ref = rp_path(np.tile(step, (20, 1)), p)
    ref = ref[:, [S_TT, S_TN, S_EPSN, S_EPSS]]
    errs = []
    for k in (1e12, 1e13):
        r = drive_path(dataclasses.replace(RP, kn=k, kt=k), path)
        got = np.column_stack([r["T_t"], r["T_n"], r["eps_n_p"], r["eps_s_p"]])
        errs.append(np.abs(got - ref).max(axis=0) / np.abs(ref).max(axis=0))
    assert np.all(errs[1] < 1.5e-3)
    ratio = errs[0] / errs[1]
    assert np.all((ratio > 8.0) & (ratio < 12.0))


# --- material-point driver ------------------------------------------------------------------


def test_drive_output_columns():
    ut = np.linspace(0.0, 1e-4, 11)[1:]
    r = drive_path(EP, np.column_stack([ut, -0.1 * ut]))
    keys = {"step", "jump_t", "jump_n", "T_t", "T_n", "jump_p_t", "jump_p_n", "eps_n_p", "eps_s_p",
            "chi", "c", "tan_phi", "tan_psi"}
    assert set(r) == keys and all(v.shape == (10,) for v in r.values())
    np.testing.assert_array_equal(r["step"], np.arange(1, 11))
    np.testing.assert_array_equal(r["jump_t"], ut)
    elastic_t = (r["jump_t"] - r["jump_p_t"]) * EP.kt
    np.testing.assert_allclose(r["T_t"], elastic_t, rtol=1e-9)


def test_drive_substeps_a_step_the_local_solve_cannot_take():
    # 0.1 m at 5 degrees with the trapezoidal work rule: the point softens through ~1e20 in one step
    # and even the rescued local solve fails (the backward-Euler 1e-2 m slip of the old test converges now)
    trap = dataclasses.replace(EP, work_rule="trapezoidal")
    p = trap.as_array()
    step = 0.1 * np.array([math.cos(math.radians(5.0)), math.sin(math.radians(5.0))])
    st, _, _ = ep(step, state(), p)
    assert st < 0
    r = drive_path(trap, step[None])
    assert abs(law.yield_function(r["T_t"][0], r["T_n"][0], r["eps_n_p"][0], r["eps_s_p"][0], p)) < 1e-8 * C_P
    matches = []
    for m in range(1, 8):
        fine = drive_path(trap, np.outer(np.arange(1, 2**m + 1) / 2**m, step))
        matches.append(abs(fine["eps_s_p"][-1] - r["eps_s_p"][0]) < 1e-9 * abs(r["eps_s_p"][0]))
    assert any(matches)  # the driver took 2^m equal sub-steps


def test_drive_rejects_rigid_law_and_reports_failing_step():
    with pytest.raises(ValueError, match="kn and kt"):
        drive_path(RP, np.zeros((2, 2)))
    with pytest.raises(RuntimeError, match="step 2"):
        drive_path(EP, np.array([[0.0, 1e-6], [np.nan, 1e-6]]))


# --- the trapezoidal work rule ------------------------------------------------------------------


TRAP = dataclasses.replace(EP, work_rule="trapezoidal")
TRAP_GF = dataclasses.replace(UNEQUAL_GF, work_rule="trapezoidal")
TRAP_RP = dataclasses.replace(RP, work_rule="trapezoidal")


def test_work_rule_is_validated_and_defaults_to_the_papers():
    assert EP.work_rule == "backward_euler" and EP.as_array()[-1] == 0.0
    assert TRAP.as_array()[-1] == 0.5
    with pytest.raises(ValueError, match="work_rule must be one of"):
        dataclasses.replace(EP, work_rule="midpoint")


def opening_errors(variant, start, steps=(40, 80, 160), u_max=1e-3):
    """Max |T_n - closed form| [Pa] along pure opening from u_n = start * chi_p / kn in n equal steps."""
    u_yield = variant.chi_p / variant.kn
    errors = []
    for n in steps:
        un = start * u_yield + np.linspace(0.0, u_max, n + 1)[1:]
        r = drive_path(variant, np.column_stack([np.zeros_like(un), un]))
        assert np.all(r["T_t"] == 0.0) and np.all(r["eps_s_p"] == 0.0)
        exact = variant.chi_p / (1.0 + 2e3 * variant.chi_p * r["jump_p_n"] / variant.GfI)
        plastic = r["jump_p_n"] > 0.0
        assert plastic.sum() >= n - 1
        errors.append(np.abs(r["T_n"] - exact)[plastic].max())
    return np.array(errors), r


@pytest.mark.parametrize("start", [1.0, 0.3], ids=["from-the-elastic-limit", "crossing-inside-a-step"])
def test_trapezoidal_pure_opening_is_second_order(start):
    """The same closed form as above; the trapezoidal rule converges as h^2, backward Euler as h."""
    variant = dataclasses.replace(TRAP_GF, c_p=2.0 * 15680.0 * math.tan(TABLE1["phi_p"]))
    errors, r = opening_errors(variant, start)
    assert r["T_n"][-1] < 0.3 * variant.chi_p
    ratios = errors[:-1] / errors[1:]
    assert np.all((ratios > 3.2) & (ratios < 4.6)), ratios  # first order would give 2
    be, _ = opening_errors(dataclasses.replace(variant, work_rule="backward_euler"), start)
    assert np.all(errors < be / 15.0)  # measured: 20x (40 steps) to 86x (160 steps) more accurate


def test_trapezoidal_work_increment_is_the_mean_of_start_and_end():
    """From a committed plastic state the opening work is (<T_old,n> + <T_n>)/2 du_n^p (eq. of R_n)."""
    p = TRAP_GF.as_array()
    st, s1, _ = ep([0.0, 3e-5], state(), p)  # onset: flow starts inside this step, at T_n = chi_p
    assert st == 1
    dup = s1[S_UPN]
    np.testing.assert_allclose(s1[S_EPSN], 0.5 * (TRAP_GF.chi_p + s1[S_TN]) * dup / TRAP_GF.GfI, rtol=1e-10)
    st, s2, _ = ep([1e-6, 2e-5], s1, p)  # continued flow, a little shear
    assert st == 1
    dup = s2[[S_UPT, S_UPN]] - s1[[S_UPT, S_UPN]]
    np.testing.assert_allclose(s2[S_EPSN] - s1[S_EPSN],
                               0.5 * (s1[S_TN] + s2[S_TN]) * dup[1] / TRAP_GF.GfI, rtol=1e-9)


TRAP_CASES = {
    "onset, tension-shear": (None, [3e-6, 2.4e-5]),
    "onset, compression-shear": (state(1000.0, -2.0e4), [3e-5, 1e-6]),
    "continued, tension-shear": ([2e-6, 2e-5], [3e-6, 2e-6]),
    "continued, compression-shear": ([6e-5, 0.0], [4e-6, 1e-7]),
}


@pytest.mark.parametrize("name", list(TRAP_CASES))
def test_trapezoidal_consistent_tangent_matches_finite_differences(name):
    """T_s moves with du in an onset step: its derivative is part of the tangent."""
    first, du = TRAP_CASES[name]
    p = TRAP_GF.as_array()
    if first is None or isinstance(first, np.ndarray):
        s_old = state() if first is None else first
    else:
        st, s_old, _ = ep(first, state(-1000.0 if first[1] < 0 else 0.0, -2.0e4 if first[1] < 0 else 0.0), p)
        assert st == 1
    st, s, d = ep(du, s_old, p)
    assert st == 1 and abs(yield_at(s, p)) < 1e-8 * C_P
    d_fd = fd_tangent(lambda u: ep(u, s_old, p)[1], du, h=5e-11)
    assert rel_err(d, d_fd) < 1e-6
    be = dataclasses.replace(TRAP_GF, work_rule="backward_euler").as_array()
    assert rel_err(ep(du, s_old, be)[2], d) > 1e-5  # the rule changes the tangent (measured 5e-5 to 1e-2)


def test_trapezoidal_rp_tangent_and_onset_rule():
    """RP: the first plastic step is backward Euler; from a plastic state the trapezoidal mean."""
    p, p_be = TRAP_RP.as_array(), RP.as_array()
    du = [1e-6, 2e-6]
    guess = np.array([0.0, 0.0, 0.0, 0.0, 0.0])
    st, s1, _ = rp(du, state(), p, guess)
    st_be, s1_be, _ = rp(du, state(), p_be, guess)
    assert st == st_be == 1
    np.testing.assert_array_equal(s1, s1_be)
    du2 = [2e-6, 1e-6]
    x1 = np.array([s1[S_TT], s1[S_TN], s1[S_EPSN], s1[S_EPSS], 0.0])
    st, s2, d = rp(du2, s1, p, x1)
    assert st == 1 and abs(yield_at(s2, p)) < 1e-8 * C_P
    np.testing.assert_allclose(s2[S_EPSN] - s1[S_EPSN],
                               0.5 * (max(s1[S_TN], 0) + max(s2[S_TN], 0)) * du2[1] / TRAP_RP.GfI, rtol=1e-9)
    d_fd = fd_tangent(lambda u: rp(u, s1, p, x1)[1], du2, 1e-11)
    assert rel_err(d, d_fd) < 1e-6


def test_frozen_predictor_rows_and_solution():
    """The frozen-strength predictor: its reduced Jacobian matches finite differences, and its result
    solves rows 0, 1 and 4 of the local problem (eq. 31 and 18) with the strengths at eps_old."""
    p = EP.as_array()
    en, es = 2e-5, 4e-5
    chi, c, tphi, tpsi = law.strengths(en, es, p)
    du, t_old, comp = np.array([3e-5, 2e-6]), np.array([500.0, -200.0]), np.array([1e-9, 1e-9])
    s, wu = law._scale(p), law._jump_weight(comp, du, p)
    tn_tr = t_old[1] + du[1] / comp[1]
    tt, dg = 9000.0, 2e-6
    rows = np.array(law._frozen_rows(tt, dg, du, t_old, comp, wu, s, tn_tr, chi, c, tphi, tpsi))
    for k, (var, h) in enumerate(((0, 1e-3), (1, 1e-12))):
        xp, xm = [tt, dg], [tt, dg]
        xp[var] += h
        xm[var] -= h
        fd = (np.array(law._frozen_rows(*xp, du, t_old, comp, wu, s, tn_tr, chi, c, tphi, tpsi)[:2])
              - np.array(law._frozen_rows(*xm, du, t_old, comp, wu, s, tn_tr, chi, c, tphi, tpsi)[:2])) / (2 * h)
        np.testing.assert_allclose(rows[[2 + k, 4 + k]], fd, rtol=1e-6)
    x = np.array([t_old[0] + du[0] / comp[0], tn_tr, en, es, 0.0])
    assert law.yield_function(x[0], x[1], en, es, p) > 0.0
    assert law._frozen_return(x, du, t_old, comp, p, 1.0)
    r, jac = np.zeros(5), np.zeros((5, 5))
    law._system(x, du, t_old, en, es, comp, wu, p, np.zeros(3), r, jac)
    assert np.abs(r[[0, 1, 4]]).max() < 1e-12 and x[4] > 0.0
    assert np.abs(r[[2, 3]]).max() > 1e-3  # the ISV rows are what the full Newton then solves


def _reference_return(du, s_old, comp, p):
    """Independent driver of the EP return: plain Newton with backtracking on the full 5 x 5 residual
    (law._system) from the trial, NumPy's solve, D = -(J^-1)[0:2, 0:2] / wu by the same residual."""
    from rockfrac.laws.cohesive_params import S_EPSN, S_EPSS, S_TN, S_TT

    en, es = s_old[S_EPSN], s_old[S_EPSS]
    t_old = s_old[[S_TT, S_TN]].copy()
    ws, dws = np.zeros(3), np.zeros((2, 2))
    law._work_start(t_old.copy(), du, comp, en, es, p, law.START_CROSSING, ws, dws)
    x = np.array([t_old[0] + du[0] / comp[0], t_old[1] + du[1] / comp[1], en, es, 0.0])
    wu = law._jump_weight(comp, du, p)
    r, jac = np.zeros(5), np.zeros((5, 5))
    law._system(x, du, t_old, en, es, comp, wu, p, ws, r, jac)
    for _ in range(100):
        if np.linalg.norm(r) < 1e-13:
            break
        dx = np.linalg.solve(jac, -r)
        a = min(1.0, 0.9 * abs(x[0] / dx[0])) if x[0] * (x[0] + dx[0]) <= 0 else 1.0
        while True:
            rt, jt = np.zeros(5), np.zeros((5, 5))
            law._system(x + a * dx, du, t_old, en, es, comp, wu, p, ws, rt, jt)
            if np.linalg.norm(rt) <= (1 - 1e-4 * a) * np.linalg.norm(r) or a < 1e-12:
                break
            a /= 2
        x, r, jac = x + a * dx, rt, jt
    b = np.zeros((5, 2))
    b[0, 0] = b[1, 1] = wu
    if ws[0] != 0.0:
        tpsi = law.strengths(x[2], x[3], p)[3]
        ng = abs(law.flow_direction(x[0], x[1], x[2], x[3], p)[0])
        b[2] = -wu / law._scale(p) * ws[0] * dws[0] * x[4] * tpsi
        b[3] = -wu / law._scale(p) * ws[0] * dws[1] * x[4] * ng
    return x, -np.linalg.solve(jac, b)[:2]


@pytest.mark.parametrize("rule,rates", [("backward_euler", {}), ("trapezoidal", {}),
                                        ("backward_euler", dict(alpha_c=1.5e3, alpha_psi=6e2))])
def test_return_map_equals_an_independent_newton(rule, rates):
    """The compiled return (frozen predictor, Newton on a reused workspace, the converged Jacobian reused
    for the tangent) lands on the solution of the same residual found by a plain NumPy Newton."""
    from rockfrac.laws.cohesive_params import S_DGAMMA, S_EPSN, S_EPSS, S_MODE, S_TN, S_TT

    p = CohesiveLaw(**{**TABLE1, **rates}, kn=1e9, kt=1e9, work_rule=rule).as_array()
    rng = np.random.default_rng(11)
    wk = law.workspace()
    n_plastic = 0
    for k in range(60):
        s_old = np.zeros(N_STATE)
        if k % 3:  # softened, loaded points
            s_old[S_EPSN], s_old[S_EPSS] = rng.uniform(0, 3e-4, 2)
            s_old[S_TT], s_old[S_TN] = rng.uniform(-3000, 3000), rng.uniform(-3000, 1000)
            s_old[S_MODE] = float(k % 2)
        du = np.array([rng.uniform(-4e-5, 4e-5), rng.uniform(-1e-5, 1e-5) if k % 4 else 0.0])
        if k % 5 == 0:
            du[0] = 0.0  # pure opening or closing
            s_old[S_TT] = 0.0
        s_new, d = np.empty(N_STATE), np.empty((2, 2))
        st = law.ep_update_jump(du[0], du[1], s_old, p, s_new, d, wk)
        assert st >= 0
        if st != 1:
            continue
        n_plastic += 1
        x, d_ref = _reference_return(du, s_old, np.array([1e-9, 1e-9]), p)
        got = s_new[[S_TT, S_TN, S_EPSN, S_EPSS, S_DGAMMA]]
        scale = np.array([1e4, 1e4, 1e-4, 1e-4, 1e-5])
        np.testing.assert_allclose(got / scale, x / scale, rtol=0, atol=1e-9)
        np.testing.assert_allclose(d, d_ref, rtol=1e-7, atol=1e-7 * np.abs(d_ref).max())
    assert n_plastic > 25
