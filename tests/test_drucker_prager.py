"""Drucker-Prager law: parameters, gradients, eq. (8), return map (closed forms) and tangents (FD)."""

import math

import numpy as np
import pytest

from rockfrac.laws import drucker_prager as dp
from rockfrac.laws.drucker_prager_params import (
    MODE_APEX,
    MODE_CONE,
    MODE_ELASTIC,
    N_STATE,
    P_B,
    P_BETA,
    P_E,
    P_H,
    P_KAPPA0,
    P_NU,
    S_DGAMMA,
    S_EPS_P,
    S_GAMMA,
    S_MODE,
    DruckerPrager,
    initial_state,
    mohr_coulomb_angle,
    mohr_coulomb_beta,
    mohr_coulomb_cohesion,
    mohr_coulomb_kappa,
)

SQ3, SQ6, SQ32 = math.sqrt(3.0), math.sqrt(6.0), math.sqrt(1.5)
ONE = np.array([1.0, 1.0, 1.0, 0.0, 0.0, 0.0])


def law(b_deg=10.0, H=2.0e5, phi_deg=30.0, c=1.0e4, nu=0.3):
    return DruckerPrager.from_mohr_coulomb(1.5e7, nu, math.radians(phi_deg), c, math.radians(b_deg), H=H)


def update(lw_or_p, eps, s_old=None):
    p = lw_or_p.as_array() if isinstance(lw_or_p, DruckerPrager) else lw_or_p
    s_old = np.zeros(N_STATE) if s_old is None else s_old
    sig, c, s_new = np.zeros(6), np.zeros((6, 6)), np.zeros(N_STATE)
    st = dp.return_map(np.asarray(eps, float), s_old, p, sig, c, s_new)
    return st, sig, c, s_new


def fd_tangent(p, eps, s_old, rel=1e-6):
    h = rel * np.abs(eps).max()
    out = np.zeros((6, 6))
    for j in range(6):
        e1, e2 = eps.copy(), eps.copy()
        e1[j] += h
        e2[j] -= h
        out[:, j] = (update(p, e1, s_old)[1] - update(p, e2, s_old)[1]) / (2 * h)
    return out


def norm_s(sig):
    s = sig - sig[:3].mean() * ONE
    return math.sqrt(s[0] ** 2 + s[1] ** 2 + s[2] ** 2 + 2 * (s[3] ** 2 + s[4] ** 2 + s[5] ** 2))


def rotate_voigt(v, R, strain):
    """Rotate a Voigt vector (strain-like if strain, else stress-like) by R."""
    f = 0.5 if strain else 1.0
    T = np.array([[v[0], f * v[3], f * v[5]], [f * v[3], v[1], f * v[4]], [f * v[5], f * v[4], v[2]]])
    T = R @ T @ R.T
    return np.array([T[0, 0], T[1, 1], T[2, 2], T[0, 1] / f, T[1, 2] / f, T[0, 2] / f])


# --- parameters ---------------------------------------------------------------------------


def test_mohr_coulomb_match_values_and_inverse():
    assert mohr_coulomb_beta(math.pi / 6) == pytest.approx(math.sqrt(3.0 / 13.0), rel=1e-14)
    assert mohr_coulomb_kappa(math.pi / 6, 1e4) == pytest.approx(3e4 / math.sqrt(13.0), rel=1e-14)
    for phi in (0.0, 0.2, 0.5236, 1.2):
        assert mohr_coulomb_angle(mohr_coulomb_beta(phi)) == pytest.approx(phi, abs=1e-13)
        c = mohr_coulomb_cohesion(mohr_coulomb_beta(phi), mohr_coulomb_kappa(phi, 9053.0))
        assert c == pytest.approx(9053.0)
    with pytest.raises(ValueError, match="beta < sqrt"):
        mohr_coulomb_angle(0.9)


def test_parameter_slots_and_moduli():
    lw = DruckerPrager(E=2e7, nu=0.25, beta=0.4, b=0.1, kappa0=5e3, H=-1e4)
    p = lw.as_array()
    assert (p[P_E], p[P_NU], p[P_BETA], p[P_B], p[P_KAPPA0], p[P_H]) == (2e7, 0.25, 0.4, 0.1, 5e3, -1e4)
    k, mu = dp.moduli(p)
    assert (k, mu) == pytest.approx((lw.K, lw.mu))
    assert np.allclose(dp.elastic_matrix(p), lw.elastic_matrix())
    assert lw.cone_modulus == pytest.approx(3 * (mu + 0.4 * 0.1 * k) + SQ3 * -1e4)
    assert initial_state(3).shape == (3, N_STATE)


@pytest.mark.parametrize(
    "kw,msg",
    [
        ({"E": 0.0}, "E must be > 0"),
        ({"nu": 0.5}, "nu must be in"),
        ({"nu": -1.0}, "nu must be in"),
        ({"beta": -0.1}, "beta must be >= 0"),
        ({"b": -0.1}, "b must be >= 0"),
        ({"kappa0": -1.0}, "kappa0 must be >= 0"),
        ({"H": -1e8}, "softens too fast"),
        ({"E": float("nan")}, "finite"),
    ],
)
def test_invalid_parameters(kw, msg):
    base = {"E": 1.5e7, "nu": 0.3, "beta": 0.4, "b": 0.1, "kappa0": 1e4, "H": 0.0}
    with pytest.raises(ValueError, match=msg):
        DruckerPrager(**{**base, **kw})
    with pytest.raises(ValueError, match="psi must be"):
        DruckerPrager.from_mohr_coulomb(1.5e7, 0.3, 0.5, 1e4, -0.1)


# --- gradients and eq. (8) -------------------------------------------------------------------

SIG = np.array([-3.0e4, -8.0e4, -5.0e4, 7.0e3, -4.0e3, 2.5e3])


def test_gradients_are_derivatives_wrt_the_voigt_stress_vector():
    """f_v = dF/d(sigma_v): shear entries are twice the tensor ones (checked by central FD)."""
    lw = law()
    p = lw.as_array()
    f, g = dp.yield_gradient(SIG, p), dp.potential_gradient(SIG, p)
    pg = p.copy()
    pg[P_BETA], pg[P_KAPPA0], pg[P_H] = p[P_B], 0.0, 0.0  # G = F with beta -> b, kappa = 0
    h = 1.0
    for k in range(6):
        d = np.zeros(6)
        d[k] = h
        dfk = (dp.yield_value(SIG + d, 0.3, p) - dp.yield_value(SIG - d, 0.3, p)) / (2 * h)
        dgk = (dp.yield_value(SIG + d, 0.0, pg) - dp.yield_value(SIG - d, 0.0, pg)) / (2 * h)
        assert dfk == pytest.approx(f[k], rel=1e-7, abs=1e-10)
        assert dgk == pytest.approx(g[k], rel=1e-7, abs=1e-10)
    ce = lw.elastic_matrix()
    assert f @ ce @ g == pytest.approx(3 * (lw.mu + lw.beta * lw.b * lw.K), rel=1e-12)


def test_perfectly_plastic_tangent_eq8_annihilates_flow_and_consistency_directions():
    lw = law(b_deg=5.0)
    p = lw.as_array()
    ce = lw.elastic_matrix()
    f, g = dp.yield_gradient(SIG, p), dp.potential_gradient(SIG, p)
    cep = dp.perfectly_plastic_tangent(ce, f, g)
    scale = np.abs(ce).max()
    assert np.abs(cep @ g).max() < 1e-12 * scale  # plastic flow at no stress rate
    assert np.abs(f @ cep).max() < 1e-12 * scale  # every stress rate stays tangent to F
    assert np.abs(cep - cep.T).max() > 1e-3 * scale  # b != beta: non-symmetric
    ref = ce - np.outer(ce @ g, ce @ f) / (f @ ce @ g)
    assert np.allclose(cep, ref, rtol=0, atol=1e-12 * scale)


def test_consistent_tangent_tends_to_eq8_as_dgamma_vanishes():
    lw = law(b_deg=5.0, H=0.0)
    p = lw.as_array()
    # elastic trial just outside the surface along a deviatoric direction from a hydrostatic state
    st0, sig0, _, _ = update(p, np.array([-2e-3, -2e-3, -2e-3, 0, 0, 0]))
    assert st0 == 0
    d = np.array([1.0, -1.0, 0.0, 0.5, 0.0, 0.0])
    lo, hi = 0.0, 1e-1
    for _ in range(200):  # find the first-yield multiple of d
        mid = 0.5 * (lo + hi)
        if update(p, np.array([-2e-3, -2e-3, -2e-3, 0, 0, 0]) + mid * d)[0] == 0:
            lo = mid
        else:
            hi = mid
    st, sig, c, s_new = update(p, np.array([-2e-3, -2e-3, -2e-3, 0, 0, 0]) + hi * (1 + 1e-9) * d)
    assert st == 1 and s_new[S_DGAMMA] < 1e-9
    f, g = dp.yield_gradient(sig, p), dp.potential_gradient(sig, p)
    cep = dp.perfectly_plastic_tangent(lw.elastic_matrix(), f, g)
    assert np.abs(c - cep).max() < 1e-6 * np.abs(cep).max()


# --- return map: closed forms -----------------------------------------------------------------


def test_pure_deviatoric_path_from_a_hydrostatic_state_is_an_exact_radial_return():
    lw = law(b_deg=8.0, H=1.0e5)
    p = lw.as_array()
    K, mu = lw.K, lw.mu
    ev = -3e-3  # volumetric strain: p_tr = K ev
    gxy = 1.2e-2  # engineering shear: s_tr,xy = mu gxy, |s_tr| = sqrt(2) mu gxy
    eps = ev / 3 * ONE + np.array([0, 0, 0, gxy, 0, 0])
    st, sig, c, s_new = update(lw, eps)
    p_tr, sn_tr = K * ev, math.sqrt(2.0) * mu * gxy
    f_tr = SQ32 * sn_tr + SQ3 * (lw.beta * p_tr - lw.kappa0)
    dg = f_tr / (3 * (mu + lw.beta * lw.b * K) + SQ3 * lw.H)
    assert st == 1 and s_new[S_MODE] == MODE_CONE
    assert s_new[S_GAMMA] == pytest.approx(dg, rel=1e-12) and dg > 0
    pm = p_tr - SQ3 * lw.b * K * dg
    sxy = (sn_tr - SQ6 * mu * dg) / math.sqrt(2.0)
    assert sig == pytest.approx(np.array([pm, pm, pm, sxy, 0, 0]), rel=1e-12, abs=1e-9)
    # flow rule: plastic volumetric strain sqrt(3) b dgamma, engineering shear 2 sqrt(3/2) dgamma / sqrt(2)
    ep = s_new[S_EPS_P:S_EPS_P + 6]
    assert ep[:3].sum() == pytest.approx(SQ3 * lw.b * dg, rel=1e-12)
    assert ep[3] == pytest.approx(SQ3 * dg, rel=1e-12)
    assert dp.yield_value(sig, s_new[S_GAMMA], p) == pytest.approx(0.0, abs=1e-9 * lw.kappa0)


@pytest.mark.parametrize("H", [2e5, 0.0, -2e5])
def test_apex_return_under_hydrostatic_tension(H):
    lw = law(b_deg=10.0, H=H)
    p = lw.as_array()
    K = lw.K
    ev = 1e-2  # p_tr = K ev >> kappa0 / beta
    st, sig, c, s_new = update(lw, ev / 3 * ONE)
    den = SQ3 * lw.beta * lw.b * K + H
    dg = (lw.beta * K * ev - lw.kappa0) / den
    pm = K * ev - SQ3 * lw.b * K * dg
    assert st == 2 and s_new[S_MODE] == MODE_APEX
    assert s_new[S_GAMMA] == pytest.approx(dg, rel=1e-12)
    assert sig == pytest.approx(pm * ONE, rel=1e-12, abs=1e-9)
    assert pm == pytest.approx((lw.kappa0 + H * dg) / lw.beta, rel=1e-12)  # F = 0 at s = 0
    assert np.allclose(c, K * H / den * np.outer(ONE, ONE), rtol=0, atol=1e-9 * K)
    assert s_new[S_EPS_P:S_EPS_P + 3].sum() == pytest.approx(SQ3 * lw.b * dg, rel=1e-10)


def test_apex_with_a_small_deviator_removes_it_and_stays_consistent():
    lw = law(b_deg=10.0, H=5e4)
    p = lw.as_array()
    eps = 1e-2 / 3 * ONE + np.array([2e-5, -1e-5, -1e-5, 3e-5, 0, 1e-5])
    st, sig, c, s_new = update(lw, eps)
    assert st == 2
    assert norm_s(sig) < 1e-9 * abs(sig[0])
    assert dp.yield_value(sig, s_new[S_GAMMA], p) == pytest.approx(0.0, abs=1e-9 * abs(sig[0]))
    # the deviatoric trial would need more than the cone allows: |s_tr| <= sqrt(6) mu dgamma
    s_tr = 2 * lw.mu * (eps - eps[:3].mean() * ONE) * np.array([1, 1, 1, 0.5, 0.5, 0.5])
    assert norm_s(s_tr) <= SQ6 * lw.mu * s_new[S_DGAMMA]


def test_no_admissible_apex_return_without_dilatancy_or_hardening():
    p = law(b_deg=0.0, H=0.0).as_array()
    st, _, _, s_new = update(p, 1e-2 / 3 * ONE)
    assert st == dp.ST_NO_RETURN
    assert np.all(s_new == 0.0)
    p2 = p.copy()
    p2[P_H] = -1e9  # X_H < 0: cone return not unique
    assert update(p2, np.array([-1e-3, -3e-2, 0, 1e-2, 0, 0]))[0] == dp.ST_NO_RETURN


def test_return_is_objective_under_rotations():
    """Rotating the strain rotates the stress: checks the Voigt shear factors end to end."""
    lw = law(b_deg=5.0)
    rng = np.random.default_rng(3)
    eps = np.array([-1e-3, -2.5e-2, 2e-3, 8e-3, -3e-3, 4e-3])
    ep_old = np.array([1e-4, -3e-4, 5e-5, 2e-4, -1e-4, 5e-5])
    s_old = np.zeros(N_STATE)
    s_old[:6], s_old[S_GAMMA] = ep_old, 2e-3
    st, sig, c, s_new = update(lw, eps, s_old)
    assert st == 1
    R, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    s_rot = s_old.copy()
    s_rot[:6] = rotate_voigt(ep_old, R, True)
    st2, sig2, _, s_new2 = update(lw, rotate_voigt(eps, R, True), s_rot)
    assert st2 == 1
    assert sig2 == pytest.approx(rotate_voigt(sig, R, False), rel=1e-10, abs=1e-8)
    assert s_new2[:6] == pytest.approx(rotate_voigt(s_new[:6], R, True), rel=1e-9, abs=1e-15)
    assert s_new2[S_GAMMA] == pytest.approx(s_new[S_GAMMA], rel=1e-12)


def test_plane_strain_input_and_plastic_strain_bookkeeping():
    lw = law(b_deg=5.0)
    p = lw.as_array()
    eps = np.array([2e-3, -2.2e-2, 0.0, 5e-3, 0.0, 0.0])  # plane strain: zz, yz, xz = 0
    st, sig, c, s_new = update(lw, eps)
    assert st == 1
    assert sig[4] == 0.0 and sig[5] == 0.0 and sig[2] != 0.0
    assert np.all(c[4:, :4] == 0.0) and np.all(c[:4, 4:] == 0.0)  # out-of-plane shear decouples
    # eps^p = eps - Ce^-1 sigma
    ep = eps - np.linalg.solve(lw.elastic_matrix(), sig)
    assert s_new[:6] == pytest.approx(ep, rel=1e-9, abs=1e-15)
    assert dp.yield_value(sig, s_new[S_GAMMA], p) == pytest.approx(0.0, abs=1e-9 * lw.kappa0)
    # unloading from there is elastic about the new plastic strain
    st2, sig2, c2, s2 = update(lw, eps * 0.9, s_new)
    assert st2 == 0 and s2[S_MODE] == MODE_ELASTIC and s2[S_GAMMA] == s_new[S_GAMMA]
    assert sig2 == pytest.approx(lw.elastic_matrix() @ (0.9 * eps - s_new[:6]), rel=1e-12)
    assert np.array_equal(c2, lw.elastic_matrix())


@pytest.mark.parametrize("b_deg,H", [(30.0, 2e5), (5.0, 2e5), (0.0, 0.0), (10.0, -2e5)])
def test_consistency_after_return_on_random_strains(b_deg, H):
    lw = law(b_deg=b_deg, H=H)
    p = lw.as_array()
    rng = np.random.default_rng(7)
    seen = set()
    for _ in range(40):
        eps = rng.normal(scale=6e-3, size=6)
        s_old = np.zeros(N_STATE)
        s_old[S_GAMMA] = abs(rng.normal(scale=1e-3))
        st, sig, _, s_new = update(p, eps, s_old)
        seen.add(st)
        if st in (1, 2):
            assert dp.yield_value(sig, s_new[S_GAMMA], p) == pytest.approx(0.0, abs=1e-8 * np.abs(sig).max())
            assert s_new[S_DGAMMA] > 0
        elif st == 0:
            assert dp.yield_value(sig, s_new[S_GAMMA], p) <= 1e-9 * np.abs(sig).max()
    assert 1 in seen


# --- tangents against central finite differences ---------------------------------------------

CASES = {
    "elastic": (np.array([-1e-4, -3e-4, 0, 1e-4, 0, 0]), 10.0, 2e5),
    "cone, nonassociative": (np.array([-1e-3, -3e-2, 2e-3, 1e-2, 3e-3, -2e-3]), 5.0, 2e5),
    "cone, associative": (np.array([-1e-3, -3e-2, 2e-3, 1e-2, 3e-3, -2e-3]), 30.0, 2e5),
    "cone, softening": (np.array([-1e-3, -3e-2, 2e-3, 1e-2, 3e-3, -2e-3]), 5.0, -2e5),
    "cone, plane strain": (np.array([1e-3, -2e-2, 0, 4e-3, 0, 0]), 5.0, 0.0),
    "apex": (np.array([4e-3, 3e-3, 2e-3, 1e-5, 0, 0]), 10.0, 2e5),
}


@pytest.mark.parametrize("name", list(CASES))
def test_consistent_tangent_against_central_differences(name):
    eps, b_deg, H = CASES[name]
    lw = law(b_deg=b_deg, H=H)
    p = lw.as_array()
    s_old = np.zeros(N_STATE)
    s_old[:6] = [1e-4, -2e-4, 0, 1e-4, 0, 0]
    s_old[S_GAMMA] = 0.01
    st, sig, c, _ = update(p, eps, s_old)
    assert st == {"elastic": 0, "apex": 2}.get(name, 1)
    cfd = fd_tangent(p, eps, s_old)
    assert np.abs(cfd - c).max() <= 1e-6 * np.abs(c).max()
    if name == "cone, nonassociative":
        assert np.abs(c - c.T).max() > 1e-2 * np.abs(c).max()
    if name == "cone, associative":
        assert np.abs(c - c.T).max() < 1e-10 * np.abs(c).max()


def test_vectorized_return_map_matches_the_pointwise_one():
    lw = law(b_deg=5.0)
    p = lw.as_array()
    rng = np.random.default_rng(11)
    n = 64
    eps = rng.normal(scale=8e-3, size=(n, 6))
    s_old = np.zeros((n, N_STATE))
    s_old[:, S_GAMMA] = np.abs(rng.normal(scale=1e-3, size=n))
    sig, c, s_new = np.zeros((n, 6)), np.zeros((n, 6, 6)), np.zeros((n, N_STATE))
    status = np.zeros(n, dtype=np.int64)
    dp.return_map_points(eps, s_old, p, sig, c, s_new, status)
    for i in range(n):
        st, sg, cc, sn = update(p, eps[i], s_old[i])
        assert status[i] == st
        assert np.array_equal(sig[i], sg) and np.array_equal(c[i], cc) and np.array_equal(s_new[i], sn)
    assert {0, 1} <= set(status.tolist())


# --- the closed-form kernel against the reference (the textbook loops it replaced) ----------------


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_fast_return_map_equals_the_reference_to_round_off(seed):
    """return_map (scalars, regrouped tangent) vs return_map_reference (Ce eps product, i, j loop):
    the same status, and sigma, C, plastic strain, gamma within 1e-13 of their natural scales
    (|Ce eps_e|, |Ce|, the strains); elastic, cone and apex points, 3D and plane strain, hardening
    and softening, many orders of magnitude of moduli and strains."""
    rng = np.random.default_rng(seed)
    seen = set()
    for _ in range(12):
        lw = DruckerPrager.from_mohr_coulomb(10 ** rng.uniform(6, 10), rng.uniform(0.0, 0.45),
                                             math.radians(rng.uniform(0, 50)), 10 ** rng.uniform(2, 6),
                                             math.radians(rng.uniform(0, 40)), H=rng.uniform(-1e4, 1e6))
        p, ce = lw.as_array(), lw.elastic_matrix()
        n = 200
        eps = rng.normal(scale=10 ** rng.uniform(-6, -2), size=(n, 6))
        eps[: n // 3, 2:] = 0.0  # plane strain
        eps[: n // 3, 3] = rng.normal(scale=1e-3, size=n // 3)
        s_old = np.zeros((n, N_STATE))
        s_old[:, :6] = rng.normal(scale=1e-4, size=(n, 6))
        s_old[:, S_GAMMA] = np.abs(rng.normal(scale=1e-3, size=n))
        for i in range(n):
            a = (np.empty(6), np.empty((6, 6)), np.empty(N_STATE))
            r = (np.empty(6), np.empty((6, 6)), np.empty(N_STATE))
            st = dp.return_map(eps[i], s_old[i], p, *a)
            assert dp.return_map_reference(eps[i], s_old[i], p, *r) == st
            seen.add(st)
            if st < 0:
                continue
            ee = eps[i] - s_old[i, :6]
            sig_scale = np.abs(ce @ ee).max()
            strain_scale = max(np.abs(ee).max(), np.abs(s_old[i, :6]).max())
            assert np.abs(a[0] - r[0]).max() <= 1e-13 * sig_scale
            assert np.abs(a[1] - r[1]).max() <= 1e-13 * np.abs(ce).max()
            assert np.abs(a[2][:6] - r[2][:6]).max() <= 1e-13 * strain_scale
            assert a[2][S_GAMMA] == pytest.approx(r[2][S_GAMMA], rel=1e-13, abs=1e-13 * strain_scale)
            assert a[2][S_MODE] == r[2][S_MODE]
            if st == 0:
                assert np.array_equal(a[1], ce)  # the elastic tangent is Ce to the last bit
                assert np.array_equal(a[2], r[2])
    assert {0, 1, 2} <= seen


def test_nan_strain_is_no_admissible_return():
    p = law().as_array()
    s_old = np.zeros(N_STATE)
    s_old[S_GAMMA] = 0.5
    eps = np.array([np.nan, 0, 0, 0, 0, 0])
    for fn in (dp.return_map, dp.return_map_reference):
        sig, c, s_new = np.zeros(6), np.zeros((6, 6)), np.zeros(N_STATE)
        assert fn(eps, s_old, p, sig, c, s_new) == dp.ST_NO_RETURN
        assert np.array_equal(s_new, s_old)
