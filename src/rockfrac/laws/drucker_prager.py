"""Small-strain nonassociative Drucker-Prager elastoplasticity (paper Sect. 3.1; EDE_NOTES).

Form, Voigt convention and slots: :mod:`rockfrac.laws.drucker_prager_params`. In short,
``F = sqrt(3/2)|s| + sqrt(3)(beta p - kappa)``, ``kappa = kappa0 + H gamma``,
``G = sqrt(3/2)|s| + sqrt(3) b p``, tension positive; order (xx, yy, zz, xy, yz, xz), strain-like
vectors with engineering shear, stress-like vectors plain.

Backward-Euler return map from the trial stress ``sigma_tr = Ce (eps - eps^p_old)``:

* cone: ``dgamma = F_tr / X_H``, ``X_H = 3 (mu + beta b K) + sqrt(3) H``,
  ``sigma = sigma_tr - dgamma Ce:g = sigma_tr - sqrt(6) mu dgamma nhat - sqrt(3) b K dgamma 1``
  with ``nhat = s_tr / |s_tr|``; admissible while ``|s| = |s_tr| - sqrt(6) mu dgamma >= 0``;
* apex (``s = 0``): the flow direction is a subgradient of G, ``sqrt(3/2) N + (b/sqrt 3) 1`` with
  ``|N| <= 1``; the deviatoric plastic strain absorbs the whole trial deviator and the volumetric
  part fixes ``dgamma = (beta p_tr - kappa_n) / (sqrt(3) beta b K + H)`` from ``F = 0``. The bound
  ``|N| <= 1`` is exactly the failure of the cone condition, so the two branches do not overlap.

Consistent tangents (derivation in the docstrings): non-symmetric on the cone when ``b != beta``;
on the apex ``K H / (sqrt(3) beta b K + H) 1 x 1`` (zero for H = 0).
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from rockfrac.compiled import inner, kernel
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
)
from rockfrac.threads import parallel_kernel

SQ2 = math.sqrt(2.0)
SQ3 = math.sqrt(3.0)
SQ6 = math.sqrt(6.0)
SQ32 = math.sqrt(1.5)

ST_ELASTIC = 0
ST_CONE = 1
ST_APEX = 2
ST_NO_RETURN = -3  # no admissible return (X <= 0: softening too fast, or apex without dilatancy)


@kernel
def moduli(p):
    """Bulk and shear moduli (K, mu) [Pa] of the parameter vector p."""
    e, nu = p[P_E], p[P_NU]
    return e / (3.0 * (1.0 - 2.0 * nu)), e / (2.0 * (1.0 + nu))


@kernel
def elastic_matrix(p):
    """Isotropic Ce (6, 6) [Pa], Voigt (xx, yy, zz, xy, yz, xz), strain-like -> stress-like."""
    k, mu = moduli(p)
    lam = k - 2.0 * mu / 3.0
    c = np.zeros((6, 6))
    for i in range(3):
        for j in range(3):
            c[i, j] = lam
        c[i, i] += 2.0 * mu
        c[i + 3, i + 3] = mu
    return c


@kernel
def deviator(sigma, s_out):
    """Mean stress p = tr(sigma)/3 [Pa]; s_out (6,) = dev(sigma) (stress-like); returns (p, |s|)."""
    p = (sigma[0] + sigma[1] + sigma[2]) / 3.0
    for i in range(3):
        s_out[i] = sigma[i] - p
        s_out[i + 3] = sigma[i + 3]
    nrm = 0.0
    for i in range(3):
        nrm += s_out[i] * s_out[i] + 2.0 * s_out[i + 3] * s_out[i + 3]
    return p, math.sqrt(nrm)


@kernel
def yield_value(sigma, gamma, p):
    """F [Pa] at stress sigma (6,) [Pa] and accumulated gamma."""
    s = np.empty(6)
    pm, sn = deviator(sigma, s)
    kappa = p[P_KAPPA0] + p[P_H] * gamma
    return SQ32 * sn + SQ3 * (p[P_BETA] * pm - kappa)


@inner
def _cone_gradient(sigma, coef, out):
    """out = sqrt(3/2) nhat + (coef/sqrt 3) 1 as a strain-like Voigt 6-vector (shears doubled).

    nhat = s/|s|; at s = 0 the deviatoric part is taken as 0 (the apex has no unique gradient).
    """
    s = np.empty(6)
    _, sn = deviator(sigma, s)
    inv = 1.0 / sn if sn > 0.0 else 0.0
    for i in range(3):
        out[i] = SQ32 * s[i] * inv + coef / SQ3
        out[i + 3] = 2.0 * SQ32 * s[i + 3] * inv
    return sn


@kernel
def yield_gradient(sigma, p):
    """f = dF/dsigma (6,), strain-like Voigt (= dF/d(sigma_v): shear entries are 2 f_ij) [-]."""
    out = np.empty(6)
    _cone_gradient(sigma, p[P_BETA], out)
    return out


@kernel
def potential_gradient(sigma, p):
    """g = dG/dsigma (6,), strain-like Voigt (shear entries are 2 g_ij) [-]."""
    out = np.empty(6)
    _cone_gradient(sigma, p[P_B], out)
    return out


@kernel
def perfectly_plastic_tangent(ce, f, g):
    """Eq. (8): c_ep = Ce - (Ce:g) x (f:Ce) / (f:Ce:g) (6, 6) [Pa]; f, g strain-like Voigt."""
    a = np.zeros(6)  # Ce:g, stress-like
    bv = np.zeros(6)  # f:Ce, stress-like
    for i in range(6):
        for j in range(6):
            a[i] += ce[i, j] * g[j]
            bv[i] += f[j] * ce[j, i]
    den = 0.0
    for i in range(6):
        den += f[i] * a[i]
    out = np.empty((6, 6))
    for i in range(6):
        for j in range(6):
            out[i, j] = ce[i, j] - a[i] * bv[j] / den
    return out


THIRD = 1.0 / 3.0
INV_SQ3 = 1.0 / SQ3
SQ18 = math.sqrt(18.0)


@inner
def _copy_state(s_old, s_new):
    for kk in range(N_STATE):
        s_new[kk] = s_old[kk]


@inner
def _cone_row(c, i, ui, vi, n0, n1, n2, n3, n4, n5):
    """Row i of the cone tangent without its I_dev diagonal: c[i, j] = ui nj + vi [j < 3]."""
    c[i, 0] = ui * n0 + vi
    c[i, 1] = ui * n1 + vi
    c[i, 2] = ui * n2 + vi
    c[i, 3] = ui * n3
    c[i, 4] = ui * n4
    c[i, 5] = ui * n5


@inner
def return_map_into(eps, s_old, p, k, mu, ce, work, sigma_out, c_out, s_new):
    """:func:`return_map` without allocations: (k, mu) = moduli(p); ce (= elastic_matrix(p)) and the
    scratch work (5, 6) are no longer read (kept in the signature for the callers).

    Closed forms on scalars, two divisions (1/X_H, 1/|s_tr|) and one square root a plastic point:

    * trial stress split as ``p_tr = K tr(eps_e)``, ``s_tr = 2 mu dev(eps_e)`` (no 6 x 6 product);
    * cone: ``sigma = r s_tr + p 1``, ``r = 1 - sqrt(6) mu dgamma / |s_tr|``, and the consistent
      tangent of :func:`return_map_reference_into` regrouped as
      ``C = 2 mu r I_dev + u x nhat + v x 1`` with ``u = G nhat - (3 sqrt2 mu b K / X_H) 1``,
      ``v = -(3 sqrt2 mu beta K / X_H) nhat + (K - 3 beta b K^2 / X_H - 2 mu r / 3) 1`` (the ``1``
      parts on the normal rows), ``G = 2 mu (1 - r) - 6 mu^2 / X_H``: a product and at most one sum
      per entry instead of the reference's 3 products, 3 sums, a division and two branches;
    * elastic: ``C = Ce`` written from (K, mu) with :func:`elastic_matrix`'s arithmetic (same bits).

    Inlined into its callers (``inline="always"``): a call per point would pass ~60 words and
    increment/decrement the reference counts of the row views, which cost more than the arithmetic.
    Equal to :func:`return_map_reference_into` to round-off (tests: 1e-13 of the trial-stress, elastic
    modulus and strain scales; the status the same).
    """
    e0 = eps[0] - s_old[S_EPS_P]
    e1 = eps[1] - s_old[S_EPS_P + 1]
    e2 = eps[2] - s_old[S_EPS_P + 2]
    e3 = eps[3] - s_old[S_EPS_P + 3]
    e4 = eps[4] - s_old[S_EPS_P + 4]
    e5 = eps[5] - s_old[S_EPS_P + 5]
    vol = e0 + e1 + e2
    p_tr = k * vol
    m2 = 2.0 * mu
    v3 = vol * THIRD
    s0 = m2 * (e0 - v3)
    s1 = m2 * (e1 - v3)
    s2 = m2 * (e2 - v3)
    s3 = mu * e3
    s4 = mu * e4
    s5 = mu * e5
    sn = math.sqrt(s0 * s0 + s1 * s1 + s2 * s2 + 2.0 * (s3 * s3 + s4 * s4 + s5 * s5))
    beta = p[P_BETA]
    b = p[P_B]
    h = p[P_H]
    gamma_n = s_old[S_GAMMA]
    kappa_n = p[P_KAPPA0] + h * gamma_n
    bp = beta * p_tr
    f_tr = SQ32 * sn + SQ3 * (bp - kappa_n)
    tol = 1.0e-12 * (SQ32 * sn + SQ3 * (abs(bp) + abs(kappa_n))) + 1.0e-300
    if f_tr <= tol:  # elastic (false for NaN: a NaN strain ends as ST_NO_RETURN below)
        sigma_out[0] = s0 + p_tr
        sigma_out[1] = s1 + p_tr
        sigma_out[2] = s2 + p_tr
        sigma_out[3] = s3
        sigma_out[4] = s4
        sigma_out[5] = s5
        lam = k - 2.0 * mu / 3.0  # as elastic_matrix(p)
        d = lam + 2.0 * mu
        for i in range(6):
            for j in range(6):
                c_out[i, j] = 0.0
        for i in range(3):
            for j in range(3):
                c_out[i, j] = lam
            c_out[i, i] = d
            c_out[i + 3, i + 3] = mu
        _copy_state(s_old, s_new)
        s_new[S_DGAMMA] = 0.0
        s_new[S_MODE] = MODE_ELASTIC
        return ST_ELASTIC
    x_h = 3.0 * (mu + beta * b * k) + SQ3 * h
    if not x_h > 0.0:
        _copy_state(s_old, s_new)
        return ST_NO_RETURN
    inv_x = 1.0 / x_h
    dg = f_tr * inv_x
    if sn - SQ6 * mu * dg > 0.0:  # cone
        inv_sn = 1.0 / sn
        n0 = s0 * inv_sn
        n1 = s1 * inv_sn
        n2 = s2 * inv_sn
        n3 = s3 * inv_sn
        n4 = s4 * inv_sn
        n5 = s5 * inv_sn
        r = 1.0 - SQ6 * mu * dg * inv_sn  # |s| / |s_tr|
        pm = p_tr - SQ3 * b * k * dg
        sigma_out[0] = r * s0 + pm
        sigma_out[1] = r * s1 + pm
        sigma_out[2] = r * s2 + pm
        sigma_out[3] = r * s3
        sigma_out[4] = r * s4
        sigma_out[5] = r * s5
        bd = m2 * r  # 2 mu - 2 sqrt(6) mu^2 dgamma / |s_tr|
        g = m2 - bd - 6.0 * mu * mu * inv_x
        q = -SQ18 * mu * k * inv_x
        qf = q * beta
        ug = q * b
        a1 = k - 3.0 * beta * b * k * k * inv_x - bd * THIRD
        _cone_row(c_out, np.int64(0), g * n0 + ug, qf * n0 + a1, n0, n1, n2, n3, n4, n5)
        _cone_row(c_out, np.int64(1), g * n1 + ug, qf * n1 + a1, n0, n1, n2, n3, n4, n5)
        _cone_row(c_out, np.int64(2), g * n2 + ug, qf * n2 + a1, n0, n1, n2, n3, n4, n5)
        _cone_row(c_out, np.int64(3), g * n3, qf * n3, n0, n1, n2, n3, n4, n5)
        _cone_row(c_out, np.int64(4), g * n4, qf * n4, n0, n1, n2, n3, n4, n5)
        _cone_row(c_out, np.int64(5), g * n5, qf * n5, n0, n1, n2, n3, n4, n5)
        c_out[0, 0] += bd
        c_out[1, 1] += bd
        c_out[2, 2] += bd
        hb = 0.5 * bd
        c_out[3, 3] += hb
        c_out[4, 4] += hb
        c_out[5, 5] += hb
        gs = SQ32 * dg  # eps^p += dgamma g, g = sqrt(3/2) nhat + (b/sqrt 3) 1 (strain-like)
        gv = b * INV_SQ3 * dg
        gs2 = 2.0 * gs
        s_new[S_EPS_P] = s_old[S_EPS_P] + (gs * n0 + gv)
        s_new[S_EPS_P + 1] = s_old[S_EPS_P + 1] + (gs * n1 + gv)
        s_new[S_EPS_P + 2] = s_old[S_EPS_P + 2] + (gs * n2 + gv)
        s_new[S_EPS_P + 3] = s_old[S_EPS_P + 3] + gs2 * n3
        s_new[S_EPS_P + 4] = s_old[S_EPS_P + 4] + gs2 * n4
        s_new[S_EPS_P + 5] = s_old[S_EPS_P + 5] + gs2 * n5
        s_new[S_GAMMA] = gamma_n + dg
        s_new[S_DGAMMA] = dg
        s_new[S_MODE] = MODE_CONE
        return ST_CONE
    # apex (s = 0): the whole trial deviator becomes plastic, dgamma from F = 0
    den = SQ3 * beta * b * k + h
    if not den > 0.0:
        _copy_state(s_old, s_new)
        return ST_NO_RETURN
    dga = (bp - kappa_n) / den
    if not dga >= 0.0:
        _copy_state(s_old, s_new)
        return ST_NO_RETURN
    pm = p_tr - SQ3 * b * k * dga
    ca = k * h / den
    for i in range(6):
        sigma_out[i] = pm if i < 3 else 0.0
        for j in range(6):
            c_out[i, j] = ca if (i < 3 and j < 3) else 0.0
    ev = pm / (3.0 * k)  # eps^p = eps - Ce^-1 sigma, Ce^-1 sigma = p / (3K) 1
    for i in range(6):
        s_new[S_EPS_P + i] = eps[i] - (ev if i < 3 else 0.0)
    s_new[S_GAMMA] = gamma_n + dga
    s_new[S_DGAMMA] = dga
    s_new[S_MODE] = MODE_APEX
    return ST_APEX


@kernel
def return_map(eps, s_old, p, sigma_out, c_out, s_new):
    """Stress sigma_out (6,) [Pa] and consistent tangent c_out (6, 6) [Pa] at total strain eps (6,).

    s_old/s_new: committed/new state (N_STATE,). Returns 0 elastic, 1 cone, 2 apex,
    -3 no admissible return (state copied, outputs undefined).
    """
    k, mu = moduli(p)
    return return_map_into(eps, s_old, p, k, mu, elastic_matrix(p), np.empty((5, 6)), sigma_out, c_out, s_new)


# --- reference path (the kernel before the rewrite) ---------------------------------------


@inner
def _ref_elastic(sig_tr, s_old, ce, sigma_out, c_out, s_new):
    """Elastic step: sigma = sigma_tr, C = Ce, plastic state unchanged."""
    for k in range(N_STATE):
        s_new[k] = s_old[k]
    s_new[S_DGAMMA] = 0.0
    s_new[S_MODE] = MODE_ELASTIC
    for i in range(6):
        sigma_out[i] = sig_tr[i]
        for j in range(6):
            c_out[i, j] = ce[i, j]
    return ST_ELASTIC


@inner
def _ref_cone_into(sig_tr, s_tr, sn_tr, dg, k, mu, x_h, p, ce, s_old, sigma_out, c_out, s_new, nh, a_g, a_f):
    """Return to the cone and its consistent tangent; nh, a_g, a_f (6,) are scratch.

    With d(dgamma) = a_f : d eps / X_H and d nhat = 2 mu / |s_tr| (I_dev - nhat x nhat) d eps:
    C = Ce - (2 sqrt(6) mu^2 dgamma / |s_tr|) (I_dev - nhat x nhat) - a_g x a_f / X_H,
    a_g = Ce:g = sqrt(6) mu nhat + sqrt(3) b K 1, a_f = Ce:f = sqrt(6) mu nhat + sqrt(3) beta K 1.
    """
    beta, b = p[P_BETA], p[P_B]
    for i in range(6):
        nh[i] = s_tr[i] / sn_tr
    for i in range(6):
        sigma_out[i] = sig_tr[i] - SQ6 * mu * dg * nh[i]
    for i in range(3):
        sigma_out[i] -= SQ3 * b * k * dg
    for i in range(6):
        a_g[i] = SQ6 * mu * nh[i]
        a_f[i] = SQ6 * mu * nh[i]
    for i in range(3):
        a_g[i] += SQ3 * b * k
        a_f[i] += SQ3 * beta * k
    c_dev = 2.0 * SQ6 * mu * mu * dg / sn_tr
    for i in range(6):
        for j in range(6):
            idev = 0.0
            if i == j:
                idev = 1.0 if i < 3 else 0.5  # I_sym from strain-like to stress-like
            if i < 3 and j < 3:
                idev -= 1.0 / 3.0
            c_out[i, j] = ce[i, j] - c_dev * (idev - nh[i] * nh[j]) - a_g[i] * a_f[j] / x_h
    for kk in range(N_STATE):
        s_new[kk] = s_old[kk]
    for i in range(3):  # eps^p += dgamma g, g = sqrt(3/2) nhat + (b/sqrt 3) 1 (strain-like)
        s_new[S_EPS_P + i] += dg * (SQ32 * nh[i] + b / SQ3)
        s_new[S_EPS_P + i + 3] += dg * 2.0 * SQ32 * nh[i + 3]
    s_new[S_GAMMA] = s_old[S_GAMMA] + dg
    s_new[S_DGAMMA] = dg
    s_new[S_MODE] = MODE_CONE
    return ST_CONE


@inner
def _ref_apex(eps, p_tr, k, kappa_n, p, s_old, sigma_out, c_out, s_new):
    """Return to the apex (s = 0): p = p_tr - sqrt(3) b K dgamma, C = K H / D 1 x 1.

    D = sqrt(3) beta b K + H; d p / d p_tr = H / D from dgamma = (beta p_tr - kappa_n) / D.
    """
    beta, b, h = p[P_BETA], p[P_B], p[P_H]
    den = SQ3 * beta * b * k + h
    if not den > 0.0:
        return ST_NO_RETURN
    dg = (beta * p_tr - kappa_n) / den
    if not dg >= 0.0:
        return ST_NO_RETURN
    pm = p_tr - SQ3 * b * k * dg
    for i in range(6):
        sigma_out[i] = pm if i < 3 else 0.0
        for j in range(6):
            c_out[i, j] = k * h / den if (i < 3 and j < 3) else 0.0
    for kk in range(N_STATE):
        s_new[kk] = s_old[kk]
    for i in range(6):  # eps^p = eps - Ce^-1 sigma, Ce^-1 sigma = p / (3K) 1
        s_new[S_EPS_P + i] = eps[i] - (pm / (3.0 * k) if i < 3 else 0.0)
    s_new[S_GAMMA] = s_old[S_GAMMA] + dg
    s_new[S_DGAMMA] = dg
    s_new[S_MODE] = MODE_APEX
    return ST_APEX


@inner
def return_map_reference_into(eps, s_old, p, k, mu, ce, work, sigma_out, c_out, s_new):
    """The return map as it was before :func:`return_map_into` was rewritten for speed (kept as the
    reference path of the tests and of ``benchmarks/kernels.py``): trial stress by the 6 x 6 product
    Ce eps, the cone tangent by the textbook sum over i, j with a division per entry. Same arguments
    and results (to round-off) as :func:`return_map_into`."""
    sig_tr = work[0]
    s_tr = work[1]
    for i in range(6):
        acc = 0.0
        for j in range(6):
            acc += ce[i, j] * (eps[j] - s_old[S_EPS_P + j])
        sig_tr[i] = acc
    p_tr, sn_tr = deviator(sig_tr, s_tr)
    beta = p[P_BETA]
    kappa_n = p[P_KAPPA0] + p[P_H] * s_old[S_GAMMA]
    f_tr = SQ32 * sn_tr + SQ3 * (beta * p_tr - kappa_n)
    tol = 1.0e-12 * (SQ32 * sn_tr + SQ3 * (abs(beta * p_tr) + abs(kappa_n))) + 1.0e-300
    if f_tr <= tol:
        return _ref_elastic(sig_tr, s_old, ce, sigma_out, c_out, s_new)
    x_h = 3.0 * (mu + beta * p[P_B] * k) + SQ3 * p[P_H]
    if not x_h > 0.0:
        for kk in range(N_STATE):
            s_new[kk] = s_old[kk]
        return ST_NO_RETURN
    dg = f_tr / x_h
    if sn_tr - SQ6 * mu * dg > 0.0:
        return _ref_cone_into(sig_tr, s_tr, sn_tr, dg, k, mu, x_h, p, ce, s_old, sigma_out, c_out, s_new,
                              work[2], work[3], work[4])
    st = _ref_apex(eps, p_tr, k, kappa_n, p, s_old, sigma_out, c_out, s_new)
    if st < 0:
        for kk in range(N_STATE):
            s_new[kk] = s_old[kk]
    return st


@kernel
def return_map_reference(eps, s_old, p, sigma_out, c_out, s_new):
    """Allocating form of :func:`return_map_reference_into` (the reference of :func:`return_map`)."""
    k, mu = moduli(p)
    return return_map_reference_into(eps, s_old, p, k, mu, elastic_matrix(p), np.empty((5, 6)), sigma_out, c_out,
                                     s_new)


@parallel_kernel(cost=0.3e-6)  # s per item, one thread (an estimate: no benchmark example calls it)
def return_map_points(eps, s_old, p, sigma, c, s_new, status):
    """Return map at n points (prange, each one a :func:`return_map`).

    eps (n, 6), s_old/s_new (n, N_STATE), sigma (n, 6), c (n, 6, 6), status (n,).
    """
    n = eps.shape[0]
    k, mu = moduli(p)
    ce = elastic_matrix(p)
    n_chunks = max(1, min(n, 256))  # scratch per chunk (a thread count here would stop caching)
    for ch in nb.prange(n_chunks):  # scratch once per chunk, not per point
        work = np.empty((5, 6))
        for i in range(ch * n // n_chunks, (ch + 1) * n // n_chunks):
            status[i] = return_map_into(eps[i], s_old[i], p, k, mu, ce, work, sigma[i], c[i], s_new[i])
