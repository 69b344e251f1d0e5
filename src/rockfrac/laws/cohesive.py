"""Tension-capped hyperbolic Mohr-Coulomb cohesive law (paper Sect. 4.2; Carol, Prat & Lopez 1997).

Local frame ``(t, n)``: index 0 tangential, 1 normal, ``T_n > 0`` tension. Tractions in Pa, jumps
and the plastic multiplier ``dgamma`` in m, ``eps_n``/``eps_s`` dimensionless. Parameter and state
slots are those of :mod:`rockfrac.laws.cohesive_params`.

One local problem serves both cohesive forms. With the compliance ``C = diag(1/kt, 1/kn)`` (EP,
Sect. 6.1) or ``C = 0`` (RP, Sect. 6.2) the unknowns ``x = (T_t, T_n, eps_n, eps_s, dgamma)`` solve

* ``R_u = du - C (T - T_old) - dgamma g(T, q) = 0``  (eq. 31 times K^-1; eq. 34 when C = 0)
* ``R_n = eps_n - eps_n_old - <T_n>_w dgamma g_n / G_f^I = 0``
* ``R_s = eps_s - eps_s_old - <|T_t| + T_n* tan(phi)>_w dgamma |g_t| / G_f^II = 0``
* ``R_F = F(T, q) = 0``  (eq. 18)

with Carol's pairing of G_f^I with opening and G_f^II with slip (PAPER_NOTES, Sect. 4.2). The flow
is backward Euler (closest point, everything at n+1). The work that drives softening,
``f_w = theta f(T_s, q_old) + (1 - theta) f(T, q)``, follows the law's ``work_rule``: backward
Euler (``theta = 0``, the paper's; first order in the step) or the trapezoidal rule (``theta =
1/2``; second order) between ``T_s``, the traction where plastic flow starts in the step, and the
end traction. EP: ``T_s`` is where the elastic path ``T_old + a K^e du`` meets ``F(T, q_old) = 0``
(``T_old`` itself when the point was plastic), so it depends on du and enters the tangent. RP: the
committed traction of a point that was plastic; the step in which a point first yields is
backward Euler (its onset traction is not known locally). The residual is solved by Newton with a
backtracking line search on a scaled norm, from the return with the strengths frozen at their old
values (two unknowns, no exponential: the guess); the consistent tangent is
``dT/d(du) = -(J^-1)[0:2, 0:2]`` with the converged Newton's Jacobian. Element kernels pass one
:func:`workspace` per chunk of points, so a plastic point allocates nothing.

Corner of a degenerate hyperbola (``a_F = c - chi tan(phi) = 0``, Table 1): ``T_t / sqrt(T_t^2 +
a^2)`` is taken as 0 when both vanish and its derivative ``a^2 / (T_t^2 + a^2)^{3/2}`` as 0 there,
so nothing divides by zero. In the EP form ``sign(T_t) = sign(T_t^tr)`` at the solution (and in the
RP form ``sign(T_t) = sign(du_t)``), so Newton steps are kept from crossing ``T_t = 0``, where
``dF/dT_t`` jumps; pure opening (``T_t = 0``) keeps ``T_t`` exactly 0.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from rockfrac.laws.cohesive_params import (
    MODE_ELASTIC,
    MODE_PLASTIC,
    N_STATE,
    P_A_C,
    P_A_CHI,
    P_A_PHI,
    P_A_PSI,
    P_C_P,
    P_C_R,
    P_CHI_P,
    P_CHI_R,
    P_CN,
    P_CT,
    P_GF1,
    P_GF2,
    P_TANPHI_P,
    P_TANPHI_R,
    P_TANPSI_P,
    P_THETA,
    S_DGAMMA,
    S_EPSN,
    S_EPSS,
    S_MODE,
    S_TN,
    S_TT,
    S_UPN,
    S_UPT,
)

MAX_ITER = 50  # local Newton iterations per solve
TOL_RES = 1.0e-12  # converged when the scaled residual norm is below this
TOL_STALL = 1.0e-9  # accepted if the line search stalls (round-off) below this
K_RP_SCALE = 1.0e10  # [Pa/m] sets the jump-row scale s / K_RP_SCALE when C = 0 and du = 0

ST_ELASTIC = 0
ST_PLASTIC = 1
ST_NO_CONVERGENCE = -1
ST_UNLOAD = -2  # dgamma < 0 or inadmissible plastic direction
ST_SINGULAR = -3  # singular Jacobian or NaN

START_NONE = 0  # no start-of-flow traction: backward Euler work for this step
START_GIVEN = 1  # the given traction is where flow starts (a committed plastic point)
START_CROSSING = 2  # flow starts where T_old + a K^e du meets the old yield surface


# --------------------------------------------------------------------------------------------
# strengths q(eps) and small safe helpers
# --------------------------------------------------------------------------------------------


@nb.njit(cache=True)
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


@nb.njit(cache=True)
def strengths(eps_n, eps_s, p):
    """Strengths (chi [Pa], c [Pa], tan phi, tan psi) at eps_n^p, eps_s^p (Sect. 4.2)."""
    q = _isv(eps_n, eps_s, p)
    return q[0], q[1], q[2], q[3]


@nb.njit(cache=True, parallel=True)
def strengths_points(eps_n, eps_s, p):
    """Strengths at many points: (n, 4) array of chi [Pa], c [Pa], tan phi, tan psi."""
    out = np.empty((eps_n.shape[0], 4))
    for i in nb.prange(eps_n.shape[0]):
        q = _isv(eps_n[i], eps_s[i], p)
        for k in range(4):
            out[i, k] = q[k]
    return out


@nb.njit(cache=True)
def _ratio(a, r):
    """a / r with 0 / 0 := 0 (the corner of a degenerate hyperbola, r = sqrt(T_t^2 + a_F^2))."""
    if r > 1.0e-280:
        return a / r
    return 0.0


@nb.njit(cache=True)
def _sign(v):
    """sign(v) with sign(0) = 0."""
    if v > 0.0:
        return 1.0
    if v < 0.0:
        return -1.0
    return 0.0


@nb.njit(cache=True)
def yield_function(Tt, Tn, eps_n, eps_s, p):
    """Yield function F [Pa] of eq. (18) at traction (T_t, T_n) [Pa] and ISVs eps_n, eps_s."""
    chi, c, tphi, _ = strengths(eps_n, eps_s, p)
    a_f = c - chi * tphi
    return math.sqrt(Tt * Tt + a_f * a_f) - (c - Tn * tphi)


@nb.njit(cache=True)
def flow_direction(Tt, Tn, eps_n, eps_s, p):
    """Plastic flow g = dG/dT = (T_t / sqrt(T_t^2 + a_G^2), tan psi), a_G = c - chi tan psi."""
    chi, c, _, tpsi = strengths(eps_n, eps_s, p)
    a_g = c - chi * tpsi
    return _ratio(Tt, math.sqrt(Tt * Tt + a_g * a_g)), tpsi


@nb.njit(cache=True, parallel=True)
def flow_points(tt, tn, eps_n, eps_s, p):
    """Flow directions dG/dT (n, 2) [-] at many points (local frame)."""
    out = np.empty((tt.shape[0], 2))
    for i in nb.prange(tt.shape[0]):
        g = flow_direction(tt[i], tn[i], eps_n[i], eps_s[i], p)
        out[i, 0] = g[0]
        out[i, 1] = g[1]
    return out


# --------------------------------------------------------------------------------------------
# the local problem: scaled residual and analytic Jacobian
# --------------------------------------------------------------------------------------------


@nb.njit(cache=True)
def _scale(p):
    """Traction scale s = c_p + chi_p [Pa] of the scaled residual."""
    return max(p[P_C_P] + p[P_CHI_P], 1.0)


@nb.njit(cache=True)
def _jump_rows(x, du, t_old, comp, wu, q, r, jac):
    """Rows 0-1: jump balance R_u [m] (eq. 31 / K; eq. 34 if C = 0) times wu [1/m]."""
    tt, dg = x[0], x[4]
    chi, c, tphi, tpsi, dchi, dc, dtphi, dtpsi = q
    a_g = c - chi * tpsi
    r_g = math.sqrt(tt * tt + a_g * a_g)
    u = _ratio(tt, r_g)  # g_t
    v = _ratio(a_g, r_g)
    dgt_dtt = _ratio(v * v, r_g)  # a_G^2 / r_G^3, 0 at a degenerate corner
    dgt_dag = -_ratio(u * v, r_g)  # -T_t a_G / r_G^3
    dag_den = dc - tpsi * dchi
    dag_des = dag_den - chi * dtpsi
    r[0] = wu * (du[0] - dg * u - comp[0] * (tt - t_old[0]))
    r[1] = wu * (du[1] - dg * tpsi - comp[1] * (x[1] - t_old[1]))
    jac[0, 0] = -wu * (comp[0] + dg * dgt_dtt)
    jac[0, 1] = 0.0
    jac[0, 2] = -wu * dg * dgt_dag * dag_den
    jac[0, 3] = -wu * dg * dgt_dag * dag_des
    jac[0, 4] = -wu * u
    jac[1, 0] = 0.0
    jac[1, 1] = -wu * comp[1]
    jac[1, 2] = 0.0
    jac[1, 3] = -wu * dg * dtpsi
    jac[1, 4] = -wu * tpsi
    return u, dgt_dtt, dgt_dag, dag_den, dag_des


@nb.njit(cache=True)
def _opening_row(x, en_old, p, q, ws, we, r, jac):
    """Row 2: G_f^I (eps_n - eps_n_old) - <T_n>_w dgamma g_n [Pa m] times we [1/(Pa m)].

    eps_n' = <T_n> u_n^p' / G_f^I (Carol's pairing, PAPER_NOTES Sect. 4.2) with the work rule's
    <T_n>_w = theta <T_s,n> + (1 - theta) <T_n>, ws = (theta, <T_s,n>, .) (see _work_start).
    """
    tn, dg = x[1], x[4]
    tpsi, dtpsi = q[3], q[7]
    gf = p[P_GF1]
    th = ws[0]
    mac = th * ws[1] + (1.0 - th) * max(tn, 0.0)
    h = (1.0 - th) if tn > 0.0 else 0.0
    r[2] = we * (gf * (x[2] - en_old) - mac * dg * tpsi)
    jac[2, 0] = 0.0
    jac[2, 1] = -we * h * dg * tpsi
    jac[2, 2] = we * gf
    jac[2, 3] = -we * mac * dg * dtpsi
    jac[2, 4] = -we * mac * tpsi


@nb.njit(cache=True)
def _slip_row(x, es_old, p, q, gt, ws, we, r, jac):
    """Row 3: G_f^II (eps_s - eps_s_old) - <|T_t| + T_n* tan phi>_w dgamma |g_t| [Pa m] times we.

    eps_s' = <|T_t| + T_n* tan phi> |u_t^p'| / G_f^II (Carol's pairing) with the work rule's mean
    theta m_s + (1 - theta) <.>, ws = (theta, ., m_s). gt = (g_t, dg_t/dT_t, dg_t/da_G,
    da_G/deps_n, da_G/deps_s) from the jump rows.
    """
    tt, tn, dg = x[0], x[1], x[4]
    tphi, dtphi = q[2], q[6]
    gf = p[P_GF2]
    sg = _sign(tt)
    ng, dng_dtt, dng_dag = sg * gt[0], sg * gt[1], sg * gt[2]
    tn_star = min(tn, 0.0)
    arg = abs(tt) + tn_star * tphi
    th = ws[0]
    m = th * ws[2] + (1.0 - th) * max(arg, 0.0)
    h = (1.0 - th) if arg > 0.0 else 0.0
    dm_dtt = h * sg
    dm_dtn = h * tphi if tn < 0.0 else 0.0
    dm_des = h * tn_star * dtphi
    r[3] = we * (gf * (x[3] - es_old) - m * dg * ng)
    jac[3, 0] = -we * dg * (dm_dtt * ng + m * dng_dtt)
    jac[3, 1] = -we * dg * dm_dtn * ng
    jac[3, 2] = -we * dg * m * dng_dag * gt[3]
    jac[3, 3] = we * (gf - dg * (dm_des * ng + m * dng_dag * gt[4]))
    jac[3, 4] = -we * m * ng


@nb.njit(cache=True)
def _yield_row(x, q, s, r, jac):
    """Row 4: F(T, q) / s of eq. (18) and its gradient (safe at the corner T_t = a_F = 0)."""
    tt, tn = x[0], x[1]
    chi, c, tphi, _, dchi, dc, dtphi, _ = q
    a_f = c - chi * tphi
    r_f = math.sqrt(tt * tt + a_f * a_f)
    v = _ratio(a_f, r_f)
    daf_den = dc - tphi * dchi
    daf_des = daf_den - chi * dtphi
    r[4] = (r_f - c + tn * tphi) / s
    jac[4, 0] = _ratio(tt, r_f) / s
    jac[4, 1] = tphi / s
    jac[4, 2] = (v * daf_den - dc) / s
    jac[4, 3] = (v * daf_des - dc + tn * dtphi) / s
    jac[4, 4] = 0.0


@nb.njit(cache=True)
def _system(x, du, t_old, en_old, es_old, comp, wu, p, ws, r, jac):
    """Scaled residual r (5,) and Jacobian jac (5, 5) of the local problem at x (see module doc).

    Row weights make every row a relative error: jump rows by wu = 1/L_u [1/m], ISV rows (in
    energy form) by wu/s, the yield row by 1/s, s = c_p + chi_p [Pa]. ws: start-of-flow terms of the
    work rule (_work_start).
    """
    s = _scale(p)
    q = _isv(x[2], x[3], p)
    gt = _jump_rows(x, du, t_old, comp, wu, q, r, jac)
    _opening_row(x, en_old, p, q, ws, wu / s, r, jac)
    _slip_row(x, es_old, p, q, gt, ws, wu / s, r, jac)
    _yield_row(x, q, s, r, jac)


@nb.njit(cache=True)
def _jump_weight(comp, du, p):
    """Weight 1/L_u [1/m] of the jump rows, L_u = max(C) s + |du| (elastic plus applied jump)."""
    lu = max(comp[0], comp[1]) * _scale(p) + math.sqrt(du[0] * du[0] + du[1] * du[1])
    if not lu > 0.0:
        lu = _scale(p) / K_RP_SCALE
    return 1.0 / lu


# --------------------------------------------------------------------------------------------
# dense solve and Newton
# --------------------------------------------------------------------------------------------


@nb.njit(cache=True)
def _gauss(a, b):
    """Solve a x = b in place (b (n, m) becomes x); row equilibration + partial pivoting.

    Returns False if a is singular or not finite. Plain loops (array expressions compile slowly);
    one division per row and per pivot, the rest multiplications (divisions dominated this 5 x 5).
    """
    n = a.shape[0]
    m = b.shape[1]
    for i in range(n):
        sc = 0.0
        for j in range(n):
            sc = max(sc, abs(a[i, j]))
        if not (sc > 0.0 and sc < np.inf):
            return False
        inv = 1.0 / sc
        for j in range(n):
            a[i, j] *= inv
        for j in range(m):
            b[i, j] *= inv
    for k in range(n):
        piv = k
        big = abs(a[k, k])
        for i in range(k + 1, n):
            if abs(a[i, k]) > big:
                piv = i
                big = abs(a[i, k])
        if not big > 1.0e-300:
            return False
        if piv != k:
            for j in range(n):
                a[k, j], a[piv, j] = a[piv, j], a[k, j]
            for j in range(m):
                b[k, j], b[piv, j] = b[piv, j], b[k, j]
        inv = 1.0 / a[k, k]
        a[k, k] = inv  # kept for the back substitution
        for i in range(k + 1, n):
            f = a[i, k] * inv
            if f != 0.0:
                for j in range(k + 1, n):
                    a[i, j] -= f * a[k, j]
                for j in range(m):
                    b[i, j] -= f * b[k, j]
    for k in range(n - 1, -1, -1):
        for j in range(m):
            acc = b[k, j]
            for i in range(k + 1, n):
                acc -= a[k, i] * b[i, j]
            b[k, j] = acc * a[k, k]
    return True


@nb.njit(cache=True)
def _norm(r):
    """Euclidean norm of the scaled (dimensionless) residual."""
    acc = 0.0
    for k in range(r.shape[0]):
        acc += r[k] * r[k]
    return math.sqrt(acc)


@nb.njit(cache=True)
def _corner_limit(x0, dx0, sgn):
    """Largest step fraction (<= 1) keeping T_t on its side (sgn) of the corner T_t = 0."""
    if sgn != 0.0 and sgn * (x0 + dx0) <= 0.0:
        return 0.9 * abs(x0) / abs(dx0)
    return 1.0


@nb.njit(cache=True)
def workspace():
    """Scratch arrays of one local solve, reused point after point (a kernel makes one per chunk).

    (r, jac, rt, jt, xt, dx, b, x, ws, dws, du, comp, t_old, t_s): residual and Jacobian of the
    iterate and of the line-search trial, trial point, Newton step (5, 1), tangent right-hand side
    (5, 2), the unknowns, the work rule's start terms, and the point's du, C, T_old and T_s.
    """
    return (np.empty(5), np.empty((5, 5)), np.empty(5), np.empty((5, 5)), np.empty(5), np.empty((5, 1)),
            np.empty((5, 2)), np.empty(5), np.empty(3), np.empty((2, 2)), np.empty(2), np.empty(2),
            np.empty(2), np.empty(2))


CONVERGED = 1  # Newton converged; the workspace's jac is the Jacobian at the solution
CONVERGED_STALLED = 2  # accepted at a stalled line search below TOL_STALL; jac is not kept


@nb.njit(cache=True)
def _newton(x, du, t_old, en_old, es_old, comp, p, ws, sgn, wk):
    """Local Newton with backtracking on the scaled residual; x (5,) updated in place.

    sgn: known sign of T_t at the solution (0: pure opening, T_t held at 0 exactly).
    Returns CONVERGED (wk's jac = J(x), unfactored), CONVERGED_STALLED, -1 not converged in
    MAX_ITER, -3 singular / NaN.
    """
    r, jac, rt, jt, xt, dx = wk[0], wk[1], wk[2], wk[3], wk[4], wk[5]
    wu = _jump_weight(comp, du, p)
    _system(x, du, t_old, en_old, es_old, comp, wu, p, ws, r, jac)
    nrm = _norm(r)
    for _ in range(MAX_ITER):
        if not nrm < np.inf:
            return ST_SINGULAR
        if nrm <= TOL_RES:
            return CONVERGED
        for k in range(5):
            dx[k, 0] = -r[k]
        if not _gauss(jac, dx):
            return ST_SINGULAR
        if sgn == 0.0:
            dx[0, 0] = 0.0
        alpha = _corner_limit(x[0], dx[0, 0], sgn)
        accepted = False
        for _ls in range(40):
            for k in range(5):
                xt[k] = x[k] + alpha * dx[k, 0]
            _system(xt, du, t_old, en_old, es_old, comp, wu, p, ws, rt, jt)
            nt = _norm(rt)
            if nt <= (1.0 - 1.0e-4 * alpha) * nrm:
                accepted = True
                break
            alpha *= 0.5
        if not accepted:
            return CONVERGED_STALLED if nrm <= TOL_STALL else ST_NO_CONVERGENCE
        for k in range(5):
            x[k] = xt[k]
            r[k] = rt[k]
            for j in range(5):
                jac[k, j] = jt[k, j]
        nrm = nt
    return CONVERGED if nrm <= TOL_RES else ST_NO_CONVERGENCE


@nb.njit(cache=True)
def _frozen_rows(tt, dg, du, t_old, comp, wu, s, tn_tr, chi, c, tphi, tpsi):
    """Rows 0 and 4 of :func:`_system` with the strengths frozen and T_n eliminated by row 1
    (T_n = T_n^tr - dgamma tan psi / kn): (r0, r4, dr0/dT_t, dr0/ddgamma, dr4/dT_t, dr4/ddgamma)."""
    a_g = c - chi * tpsi
    r_g = math.sqrt(tt * tt + a_g * a_g)
    u = _ratio(tt, r_g)
    v = _ratio(a_g, r_g)
    a_f = c - chi * tphi
    r_f = math.sqrt(tt * tt + a_f * a_f)
    tn = tn_tr - dg * tpsi / comp[1]
    r0 = wu * (du[0] - dg * u - comp[0] * (tt - t_old[0]))
    r4 = (r_f - c + tn * tphi) / s
    return (r0, r4, -wu * (comp[0] + dg * _ratio(v * v, r_g)), -wu * u, _ratio(tt, r_f) / s,
            -tphi * tpsi / (comp[1] * s))


@nb.njit(cache=True)
def _frozen_return(x, du, t_old, comp, p, sgn):
    """Guess of the EP return (eq. 31) with the strengths frozen at x's ISVs, from x = the trial.

    The frozen problem is rows 0, 1, 4 of the local problem with eps = eps_old; row 1 is linear in
    (T_n, dgamma), so Newton with backtracking runs on (T_t, dgamma) alone (no exponential, a 2 x 2
    solve). Updates x's T_t, T_n, dgamma; returns False if it does not converge (x then unusable).
    """
    chi, c, tphi, tpsi = strengths(x[2], x[3], p)
    s = _scale(p)
    wu = _jump_weight(comp, du, p)
    tn_tr = t_old[1] + du[1] / comp[1]
    tt, dg = x[0], x[4]
    r0, r4, j00, j04, j40, j44 = _frozen_rows(tt, dg, du, t_old, comp, wu, s, tn_tr, chi, c, tphi, tpsi)
    nrm = math.sqrt(r0 * r0 + r4 * r4)
    ok = False
    for _ in range(MAX_ITER):
        if not nrm < np.inf:
            return False
        if nrm <= TOL_RES:
            ok = True
            break
        det = j00 * j44 - j04 * j40
        if not abs(det) > 0.0:
            return False
        d_tt = (j04 * r4 - j44 * r0) / det
        d_dg = (j40 * r0 - j00 * r4) / det
        if sgn == 0.0:
            d_tt = 0.0
        alpha = _corner_limit(tt, d_tt, sgn)
        accepted = False
        for _ls in range(40):
            tt_t, dg_t = tt + alpha * d_tt, dg + alpha * d_dg
            rows = _frozen_rows(tt_t, dg_t, du, t_old, comp, wu, s, tn_tr, chi, c, tphi, tpsi)
            nt = math.sqrt(rows[0] * rows[0] + rows[1] * rows[1])
            if nt <= (1.0 - 1.0e-4 * alpha) * nrm:
                accepted = True
                break
            alpha *= 0.5
        if not accepted:
            ok = nrm <= TOL_STALL
            break
        tt, dg = tt_t, dg_t
        r0, r4, j00, j04, j40, j44 = rows
        nrm = nt
    if not (ok or nrm <= TOL_RES):
        return False
    x[0], x[1], x[4] = tt, tn_tr - dg * tpsi / comp[1], dg
    return True


@nb.njit(cache=True)
def _tangent(x, du, t_old, en_old, es_old, comp, p, ws, dws, D, wk, have_jac):
    """Consistent tangent D = dT/d(du) [Pa/m] = -(J^-1)[0:2, 0:2] (unscaled); False if singular.

    dws (2, 2): d(<T_s,n>, m_s)/d(du) of the work rule's start terms (zero unless T_s moves with du).
    have_jac: wk's jac already holds J(x) (a converged Newton's), else it is evaluated here.
    """
    r, jac, b = wk[0], wk[1], wk[6]
    wu = _jump_weight(comp, du, p)
    if not have_jac:
        _system(x, du, t_old, en_old, es_old, comp, wu, p, ws, r, jac)
    for k in range(5):
        b[k, 0] = 0.0
        b[k, 1] = 0.0
    b[0, 0] = wu  # d r / d du of the weighted jump rows
    b[1, 1] = wu
    if ws[0] != 0.0:  # the ISV rows through T_s(du)
        we = wu / _scale(p)
        tpsi = _isv(x[2], x[3], p)[3]
        ng = abs(flow_direction(x[0], x[1], x[2], x[3], p)[0])
        for j in range(2):
            b[2, j] = -we * ws[0] * dws[0, j] * x[4] * tpsi
            b[3, j] = -we * ws[0] * dws[1, j] * x[4] * ng
    if not _gauss(jac, b):
        return False
    for i in range(2):
        for j in range(2):
            D[i, j] = -b[i, j]
    return True


@nb.njit(cache=True)
def _commit(x, up_inc_t, up_inc_n, s_old, s_new):
    """Write the plastic state x = (T_t, T_n, eps_n, eps_s, dgamma) and u^p increment to s_new."""
    for k in range(N_STATE):
        s_new[k] = s_old[k]
    s_new[S_TT] = x[0]
    s_new[S_TN] = x[1]
    s_new[S_UPT] = s_old[S_UPT] + up_inc_t
    s_new[S_UPN] = s_old[S_UPN] + up_inc_n
    s_new[S_EPSN] = x[2]
    s_new[S_EPSS] = x[3]
    s_new[S_DGAMMA] = x[4]
    s_new[S_MODE] = MODE_PLASTIC


# --------------------------------------------------------------------------------------------
# work rule: where plastic flow starts in the step
# --------------------------------------------------------------------------------------------


@nb.njit(cache=True)
def _work_start(t_s, du, comp, en_old, es_old, p, start, ws, dws):
    """Start-of-flow terms of the work rule: ws = (theta, <T_s,n>, <|T_s,t| + T_s,n* tan phi_old>) [-, Pa, Pa]
    and dws = their du-derivatives [Pa/m] (rows 1-2 of ws).

    theta = p[P_THETA] (0: backward Euler, nothing else is needed). start: START_GIVEN, T_s = t_s;
    START_CROSSING, T_s = t_s + a K^e du where F(T_s, q_old) = 0, a in [0, 1] (a = 0 if t_s is on
    the surface); F is convex along the path and positive at a = 1, so Newton from a = 1 decreases
    monotonically to the root. START_NONE: theta := 0.
    """
    for k in range(3):
        ws[k] = 0.0
    for i in range(2):
        for j in range(2):
            dws[i, j] = 0.0
    if p[P_THETA] == 0.0 or start == START_NONE:
        return
    ws[0] = p[P_THETA]
    chi, c, tphi, _ = strengths(en_old, es_old, p)
    tt, tn = t_s[0], t_s[1]
    dtt0 = dtt1 = dtn0 = dtn1 = 0.0  # dT_s/d(du)
    if start == START_CROSSING and yield_function(tt, tn, en_old, es_old, p) < -elastic_tolerance(p):
        kdt, kdn = du[0] / comp[0], du[1] / comp[1]
        a_f = c - chi * tphi
        a = 1.0
        slope = 0.0
        for _ in range(60):
            xt, xn = tt + a * kdt, tn + a * kdn
            r_f = math.sqrt(xt * xt + a_f * a_f)
            slope = _ratio(xt, r_f) * kdt + tphi * kdn
            if not slope > 0.0:
                break
            step = (r_f - c + xn * tphi) / slope
            a = min(max(a - step, 0.0), 1.0)
            if abs(step) <= 1.0e-15:
                break
        xt, xn = tt + a * kdt, tn + a * kdn
        if slope > 0.0:  # implicit function: F_T . K^e (du da + a d(du)) = 0
            r_f = math.sqrt(xt * xt + a_f * a_f)
            ft = _ratio(xt, r_f)
            da0 = -a * ft / comp[0] / slope
            da1 = -a * tphi / comp[1] / slope
            dtt0, dtt1 = kdt * da0 + a / comp[0], kdt * da1
            dtn0, dtn1 = kdn * da0, kdn * da1 + a / comp[1]
        tt, tn = xt, xn
    if tn > 0.0:
        ws[1] = tn
        dws[0, 0], dws[0, 1] = dtn0, dtn1
    arg = abs(tt) + min(tn, 0.0) * tphi
    if arg > 0.0:
        ws[2] = arg
        sg = _sign(tt)
        kn = tphi if tn < 0.0 else 0.0
        dws[1, 0] = sg * dtt0 + kn * dtn0
        dws[1, 1] = sg * dtt1 + kn * dtn1


# --------------------------------------------------------------------------------------------
# EP form (Sect. 6.1, eq. 30-31)
# --------------------------------------------------------------------------------------------


@nb.njit(cache=True)
def elastic_tolerance(p):
    """Yield tolerance [Pa]: F <= tol is elastic."""
    return 1.0e-10 * max(p[P_C_P], p[P_CHI_P], 1.0)


@nb.njit(cache=True)
def elastic_update(tt, tn, ct, cn, s_old, s_new, D):
    """Elastic step on scalars: T = (tt, tn) [Pa], D = diag(1/ct, 1/cn) [Pa/m], ISVs unchanged."""
    for k in range(N_STATE):
        s_new[k] = s_old[k]
    s_new[S_TT] = tt
    s_new[S_TN] = tn
    s_new[S_DGAMMA] = 0.0
    s_new[S_MODE] = MODE_ELASTIC
    D[0, 0] = 1.0 / ct
    D[0, 1] = 0.0
    D[1, 0] = 0.0
    D[1, 1] = 1.0 / cn
    return ST_ELASTIC


@nb.njit(cache=True)
def return_map(du, s_old, comp, p, s_new, D):
    """Backward-Euler return (eq. 30-31) from T^tr = T_old + K^e du, K^e = diag(1/comp) [Pa/m].

    du (2,): local jump increment [m]; s_old/s_new: committed/new state (N_STATE,), T_old is
    s_old's traction; D (2, 2): consistent tangent dT/d(du) [Pa/m]. The EP CSE passes its
    penalty compliances; flow starts where the elastic path leaves the old surface.
    Returns 0 elastic, 1 plastic, < 0 failure (-1 no convergence, -2 dgamma < 0, -3 singular/NaN).
    """
    return return_step(du[0], du[1], s_old[S_TT], s_old[S_TN], s_old[S_TT], s_old[S_TN], START_CROSSING,
                       comp[0], comp[1], s_old, p, s_new, D, workspace())


@nb.njit(cache=True)
def return_map_from(du, s_old, t_s, start, comp, p, s_new, D):
    """:func:`return_map` with the work rule's start-of-flow traction t_s (2,) [Pa] and its start kind.

    The RP CSE passes its augmentation (K^e = r I), T_old = lambda in s_old, and the committed
    traction with START_GIVEN (committed plastic) or START_NONE (see the module doc).
    """
    return return_step(du[0], du[1], s_old[S_TT], s_old[S_TN], t_s[0], t_s[1], start, comp[0], comp[1],
                       s_old, p, s_new, D, workspace())


@nb.njit(cache=True, inline="always")
def return_step(du_t, du_n, t_old_t, t_old_n, t_s_t, t_s_n, start, ct, cn, s_old, p, s_new, D, wk):
    """:func:`return_map_from` on scalars and a caller's :func:`workspace` (allocates nothing).

    (du_t, du_n) [m]: local jump increment; (t_old_t, t_old_n) [Pa]: the traction of the trial
    T^tr = T_old + K^e du, K^e = diag(1/ct, 1/cn); (t_s_t, t_s_n), start: the work rule's
    start-of-flow traction. s_old supplies the ISVs and plastic jumps (its traction is not read).
    Inlined: the elastic test and update run in the caller's loop, and only a yielding point makes
    a call that takes wk (passing the workspace tuple costs its 14 arrays' reference counts, ~0.1 us,
    measured).
    """
    tt = t_old_t + du_t / ct  # trial traction T^tr = T_n + K^e du (eq. 31)
    tn = t_old_n + du_n / cn
    if yield_function(tt, tn, s_old[S_EPSN], s_old[S_EPSS], p) <= elastic_tolerance(p):
        return elastic_update(tt, tn, ct, cn, s_old, s_new, D)
    return _plastic_step(du_t, du_n, t_old_t, t_old_n, tt, tn, t_s_t, t_s_n, start, ct, cn, s_old, p, s_new, D,
                         wk)


@nb.njit(cache=True)
def _plastic_step(du_t, du_n, t_old_t, t_old_n, tt, tn, t_s_t, t_s_n, start, ct, cn, s_old, p, s_new, D, wk):
    """The return of :func:`return_step` from the trial (tt, tn) [Pa], which is outside the surface."""
    en_old, es_old = s_old[S_EPSN], s_old[S_EPSS]
    x, ws, dws, du, comp, t_old, t_s = wk[7], wk[8], wk[9], wk[10], wk[11], wk[12], wk[13]
    du[0], du[1] = du_t, du_n
    comp[0], comp[1] = ct, cn
    t_old[0], t_old[1] = t_old_t, t_old_n
    t_s[0], t_s[1] = t_s_t, t_s_n
    _work_start(t_s, du, comp, en_old, es_old, p, start, ws, dws)
    x[0], x[1], x[2], x[3], x[4] = tt, tn, en_old, es_old, 0.0
    sgn = _sign(tt)  # T_t (1 + kt dgamma / r_G) = T_t^tr: the sign is that of the trial
    if not _frozen_return(x, du, t_old, comp, p, sgn):
        x[0], x[1], x[2], x[3], x[4] = tt, tn, en_old, es_old, 0.0
    st = _newton(x, du, t_old, en_old, es_old, comp, p, ws, sgn, wk)
    if st < 0:
        return st
    if x[4] < 0.0:
        return ST_UNLOAD
    if not _tangent(x, du, t_old, en_old, es_old, comp, p, ws, dws, D, wk, st == CONVERGED):
        return ST_SINGULAR
    gt, gn = flow_direction(x[0], x[1], x[2], x[3], p)
    _commit(x, x[4] * gt, x[4] * gn, s_old, s_new)
    return ST_PLASTIC


@nb.njit(cache=True)
def ep_update(du, s_old, p, s_new, D):
    """EP return map (eq. 30-31) with the law's K^e = diag(kt, kn), for the local jump increment du [m]."""
    return ep_update_jump(du[0], du[1], s_old, p, s_new, D, workspace())


@nb.njit(cache=True, inline="always")
def ep_update_jump(du_t, du_n, s_old, p, s_new, D, wk):
    """:func:`ep_update` for the increment (du_t, du_n) [m] on a caller's :func:`workspace`."""
    return return_step(du_t, du_n, s_old[S_TT], s_old[S_TN], s_old[S_TT], s_old[S_TN], START_CROSSING,
                       p[P_CT], p[P_CN], s_old, p, s_new, D, wk)


CHUNK = 256  # points per prange item: one workspace each, small enough to balance plastic clusters


@nb.njit(cache=True, parallel=True)
def ep_update_points(du, s_old, p, s_new, D, status):
    """EP return map at n points: du (n, 2) [m], s_old/s_new (n, N_STATE), D (n, 2, 2), status (n,)."""
    n = du.shape[0]
    for c in nb.prange((n + CHUNK - 1) // CHUNK):
        wk = workspace()
        for i in range(c * CHUNK, min(n, (c + 1) * CHUNK)):
            status[i] = ep_update_jump(du[i, 0], du[i, 1], s_old[i], p, s_new[i], D[i], wk)


# --------------------------------------------------------------------------------------------
# RP form (Sect. 6.2, eq. 34)
# --------------------------------------------------------------------------------------------


@nb.njit(cache=True)
def _rp_admissible(du, p):
    """False if du cannot be dgamma g with dgamma > 0: g_n = tan psi >= 0 (zero iff tan psi_p = 0)."""
    if du[0] == 0.0 and du[1] == 0.0:
        return False
    if du[1] < 0.0:
        return False
    if p[P_TANPSI_P] > 0.0:
        return du[1] > 0.0
    return du[1] == 0.0


@nb.njit(cache=True)
def _rp_direct_guess(du, s_old, p, x):
    """Frozen-ISV closed form of eq. (34): dgamma = du_n / tan psi, g_t = du_t / dgamma, F = 0.

    Returns False when |g_t| >= 1 (no frozen solution) or tan psi = 0.
    """
    en, es = s_old[S_EPSN], s_old[S_EPSS]
    chi, c, tphi, tpsi = strengths(en, es, p)
    if not (tpsi > 0.0 and tphi > 0.0):
        return False
    dg = du[1] / tpsi
    gt = du[0] / dg
    if not abs(gt) < 1.0:
        return False
    tt = (c - chi * tpsi) * gt / math.sqrt(1.0 - gt * gt)
    a_f = c - chi * tphi
    x[0], x[2], x[3], x[4] = tt, en, es, dg
    x[1] = (c - math.sqrt(tt * tt + a_f * a_f)) / tphi
    return True


@nb.njit(cache=True)
def _rp_work_start(du, s_old, p, wk):
    """Work-rule start terms of eq. (34) into wk's ws, dws: the committed traction of a plastic point,
    else none. Sets wk's T_old and C to zero (the rigid form)."""
    ws, dws, comp, t_old, t_s = wk[8], wk[9], wk[11], wk[12], wk[13]
    t_s[0] = s_old[S_TT]
    t_s[1] = s_old[S_TN]
    for k in range(2):
        comp[k] = 0.0
        t_old[k] = 0.0
    start = START_GIVEN if s_old[S_MODE] == MODE_PLASTIC else START_NONE
    _work_start(t_s, du, comp, s_old[S_EPSN], s_old[S_EPSS], p, start, ws, dws)  # no K^e used


@nb.njit(cache=True)
def _rp_solve(du, s_old, p, x, sgn, wk):
    """Newton on eq. (34) from x with T_t put on the side sgn; returns the Newton status."""
    _rp_work_start(du, s_old, p, wk)
    if sgn == 0.0:
        x[0] = 0.0
    elif x[0] * sgn <= 0.0:
        x[0] = sgn * max(abs(x[0]), 1.0e-6 * _scale(p))
    if not x[4] > 0.0:
        x[4] = math.sqrt(du[0] * du[0] + du[1] * du[1])
    return _newton(x, du, wk[12], s_old[S_EPSN], s_old[S_EPSS], wk[11], p, wk[8], sgn, wk)


@nb.njit(cache=True)
def rp_update(du, s_old, p, x_guess, s_new, D):
    """RP local problem (eq. 34) for the plastic jump increment du (2,) [m] since s_old.

    x_guess (5,): initial (T_t, T_n, eps_n, eps_s, dgamma), not modified. Fills s_new (u^p += du)
    and D = dT/d(du) [Pa/m]. Returns 1 on success, -2 if du is not an admissible plastic direction
    or dgamma < 0 (the point unloads to the constrained state), -1/-3 on failure.
    """
    for k in range(N_STATE):
        s_new[k] = s_old[k]
    if not _rp_admissible(du, p):
        return ST_UNLOAD
    sgn = _sign(du[0])  # du_t = dgamma g_t with dgamma > 0
    wk = workspace()
    x = wk[7]
    for k in range(5):
        x[k] = x_guess[k]
    st = _rp_solve(du, s_old, p, x, sgn, wk)
    if st < 0 or not x[4] > 0.0:
        if not _rp_direct_guess(du, s_old, p, x):
            for k in range(5):
                x[k] = x_guess[k]
        st = _rp_solve(du, s_old, p, x, sgn, wk)
    if st < 0:
        return st
    if not x[4] > 0.0:
        return ST_UNLOAD
    if not _tangent(x, du, wk[12], s_old[S_EPSN], s_old[S_EPSS], wk[11], p, wk[8], wk[9], D, wk,
                    st == CONVERGED):
        return ST_SINGULAR
    _commit(x, du[0], du[1], s_old, s_new)
    return ST_PLASTIC


@nb.njit(cache=True)
def rp_tangent_at(x, du, s_old, p, D):
    """D = dT/d(du) [Pa/m] of the RP local problem (eq. 34) evaluated at x (5,); 0 ok, -3 singular."""
    wk = workspace()
    _rp_work_start(du, s_old, p, wk)
    if _tangent(x, du, wk[12], s_old[S_EPSN], s_old[S_EPSS], wk[11], p, wk[8], wk[9], D, wk, False):
        return 0
    return ST_SINGULAR
