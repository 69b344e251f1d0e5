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

SQ2 = math.sqrt(2.0)
SQ3 = math.sqrt(3.0)
SQ6 = math.sqrt(6.0)
SQ32 = math.sqrt(1.5)

ST_ELASTIC = 0
ST_CONE = 1
ST_APEX = 2
ST_NO_RETURN = -3  # no admissible return (X <= 0: softening too fast, or apex without dilatancy)


@nb.njit(cache=True)
def moduli(p):
    """Bulk and shear moduli (K, mu) [Pa] of the parameter vector p."""
    e, nu = p[P_E], p[P_NU]
    return e / (3.0 * (1.0 - 2.0 * nu)), e / (2.0 * (1.0 + nu))


@nb.njit(cache=True)
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


@nb.njit(cache=True)
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


@nb.njit(cache=True)
def yield_value(sigma, gamma, p):
    """F [Pa] at stress sigma (6,) [Pa] and accumulated gamma."""
    s = np.empty(6)
    pm, sn = deviator(sigma, s)
    kappa = p[P_KAPPA0] + p[P_H] * gamma
    return SQ32 * sn + SQ3 * (p[P_BETA] * pm - kappa)


@nb.njit(cache=True)
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


@nb.njit(cache=True)
def yield_gradient(sigma, p):
    """f = dF/dsigma (6,), strain-like Voigt (= dF/d(sigma_v): shear entries are 2 f_ij) [-]."""
    out = np.empty(6)
    _cone_gradient(sigma, p[P_BETA], out)
    return out


@nb.njit(cache=True)
def potential_gradient(sigma, p):
    """g = dG/dsigma (6,), strain-like Voigt (shear entries are 2 g_ij) [-]."""
    out = np.empty(6)
    _cone_gradient(sigma, p[P_B], out)
    return out


@nb.njit(cache=True)
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


@nb.njit(cache=True)
def _elastic(sig_tr, s_old, ce, sigma_out, c_out, s_new):
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


@nb.njit(cache=True)
def _cone(sig_tr, s_tr, sn_tr, dg, k, mu, x_h, p, ce, s_old, sigma_out, c_out, s_new):
    """Return to the cone and its consistent tangent (allocating form of :func:`_cone_into`)."""
    return _cone_into(sig_tr, s_tr, sn_tr, dg, k, mu, x_h, p, ce, s_old, sigma_out, c_out, s_new,
                      np.empty(6), np.empty(6), np.empty(6))


@nb.njit(cache=True)
def _cone_into(sig_tr, s_tr, sn_tr, dg, k, mu, x_h, p, ce, s_old, sigma_out, c_out, s_new, nh, a_g, a_f):
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


@nb.njit(cache=True)
def _apex(eps, p_tr, k, kappa_n, p, s_old, sigma_out, c_out, s_new):
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


@nb.njit(cache=True)
def return_map(eps, s_old, p, sigma_out, c_out, s_new):
    """Stress sigma_out (6,) [Pa] and consistent tangent c_out (6, 6) [Pa] at total strain eps (6,).

    s_old/s_new: committed/new state (N_STATE,). Returns 0 elastic, 1 cone, 2 apex,
    -3 no admissible return (state copied, outputs undefined).
    """
    k, mu = moduli(p)
    return return_map_into(eps, s_old, p, k, mu, elastic_matrix(p), np.empty((5, 6)), sigma_out, c_out, s_new)


@nb.njit(cache=True)
def return_map_into(eps, s_old, p, k, mu, ce, work, sigma_out, c_out, s_new):
    """:func:`return_map` without allocations: (k, mu) = moduli(p), ce = elastic_matrix(p), work (5, 6)
    scratch. Same arithmetic, so the same results to the last bit."""
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
        return _elastic(sig_tr, s_old, ce, sigma_out, c_out, s_new)
    x_h = 3.0 * (mu + beta * p[P_B] * k) + SQ3 * p[P_H]
    if not x_h > 0.0:
        for kk in range(N_STATE):
            s_new[kk] = s_old[kk]
        return ST_NO_RETURN
    dg = f_tr / x_h
    if sn_tr - SQ6 * mu * dg > 0.0:
        return _cone_into(sig_tr, s_tr, sn_tr, dg, k, mu, x_h, p, ce, s_old, sigma_out, c_out, s_new,
                          work[2], work[3], work[4])
    st = _apex(eps, p_tr, k, kappa_n, p, s_old, sigma_out, c_out, s_new)
    if st < 0:
        for kk in range(N_STATE):
            s_new[kk] = s_old[kk]
    return st


@nb.njit(cache=True, parallel=True)
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
