"""Cohesive surface (Sect. 4.2): strengths q(eps), yield function, flow direction, yield tolerance."""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from rockfrac.compiled import inner, kernel
from rockfrac.laws.cohesive_params import (
    P_A_C,
    P_A_CHI,
    P_A_PHI,
    P_A_PSI,
    P_C_P,
    P_C_R,
    P_CHI_P,
    P_CHI_R,
    P_TANPHI_P,
    P_TANPHI_R,
    P_TANPSI_P,
)
from rockfrac.threads import parallel_kernel

# --------------------------------------------------------------------------------------------
# strengths q(eps) and small safe helpers
# --------------------------------------------------------------------------------------------


@inner
def _isv(eps_n, eps_s, p):
    """chi, c [Pa], tan phi, tan psi and d chi/dw, dc/dw [Pa], d tanphi/d eps_s, d tanpsi/d eps_s.

    w = eps_n + eps_s; the exponential softening laws of Sect. 4.2.
    """
    w = eps_n + eps_s
    e_chi = math.exp(-p[P_A_CHI] * w)  # equal rates (Table 1: chi with c, phi with psi) share one exp
    e_c = e_chi if p[P_A_C] == p[P_A_CHI] else math.exp(-p[P_A_C] * w)
    e_phi = math.exp(-p[P_A_PHI] * eps_s)
    e_psi = e_phi if p[P_A_PSI] == p[P_A_PHI] else math.exp(-p[P_A_PSI] * eps_s)
    d_chi = p[P_CHI_P] - p[P_CHI_R]
    d_c = p[P_C_P] - p[P_C_R]
    d_phi = p[P_TANPHI_P] - p[P_TANPHI_R]
    chi = p[P_CHI_R] + d_chi * e_chi
    c = p[P_C_R] + d_c * e_c
    tphi = p[P_TANPHI_R] + d_phi * e_phi
    tpsi = p[P_TANPSI_P] * e_psi
    return (chi, c, tphi, tpsi, -p[P_A_CHI] * d_chi * e_chi, -p[P_A_C] * d_c * e_c,
            -p[P_A_PHI] * d_phi * e_phi, -p[P_A_PSI] * tpsi)


@kernel
def strengths(eps_n, eps_s, p):
    """Strengths (chi [Pa], c [Pa], tan phi, tan psi) at eps_n^p, eps_s^p (Sect. 4.2)."""
    q = _isv(eps_n, eps_s, p)
    return q[0], q[1], q[2], q[3]


@parallel_kernel(cost=0.05e-6)  # s per item, one thread (an estimate: no benchmark example calls it)
def strengths_points(eps_n, eps_s, p):
    """Strengths at many points: (n, 4) array of chi [Pa], c [Pa], tan phi, tan psi."""
    out = np.empty((eps_n.shape[0], 4))
    for i in nb.prange(eps_n.shape[0]):
        q = _isv(eps_n[i], eps_s[i], p)
        for k in range(4):
            out[i, k] = q[k]
    return out


@kernel
def _ratio(a, r):
    """a / r with 0 / 0 := 0 (the corner of a degenerate hyperbola, r = sqrt(T_t^2 + a_F^2))."""
    if r > 1.0e-280:
        return a / r
    return 0.0


@inner
def _sign(v):
    """sign(v) with sign(0) = 0."""
    if v > 0.0:
        return 1.0
    if v < 0.0:
        return -1.0
    return 0.0


@kernel
def yield_function(Tt, Tn, eps_n, eps_s, p):
    """Yield function F [Pa] of eq. (18) at traction (T_t, T_n) [Pa] and ISVs eps_n, eps_s."""
    chi, c, tphi, _ = strengths(eps_n, eps_s, p)
    a_f = c - chi * tphi
    return math.sqrt(Tt * Tt + a_f * a_f) - (c - Tn * tphi)


@kernel
def flow_direction(Tt, Tn, eps_n, eps_s, p):
    """Plastic flow g = dG/dT = (T_t / sqrt(T_t^2 + a_G^2), tan psi), a_G = c - chi tan psi."""
    chi, c, _, tpsi = strengths(eps_n, eps_s, p)
    a_g = c - chi * tpsi
    return _ratio(Tt, math.sqrt(Tt * Tt + a_g * a_g)), tpsi


@parallel_kernel(cost=0.05e-6)  # s per item, one thread (an estimate: no benchmark example calls it)
def flow_points(tt, tn, eps_n, eps_s, p):
    """Flow directions dG/dT (n, 2) [-] at many points (local frame)."""
    out = np.empty((tt.shape[0], 2))
    for i in nb.prange(tt.shape[0]):
        g = flow_direction(tt[i], tn[i], eps_n[i], eps_s[i], p)
        out[i, 0] = g[0]
        out[i, 1] = g[1]
    return out


@inner
def elastic_tolerance(p):
    """Yield tolerance [Pa]: F <= tol is elastic."""
    return 1.0e-10 * max(p[P_C_P], p[P_CHI_P], 1.0)
