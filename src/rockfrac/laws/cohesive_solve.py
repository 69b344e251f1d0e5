"""Cohesive local solve: dense Gauss, Newton, frozen-strength guess, consistent tangent, commit."""

from __future__ import annotations

import math

import numpy as np

from rockfrac.compiled import inner, kernel
from rockfrac.laws.cohesive_params import (
    MODE_PLASTIC,
    N_STATE,
    S_DGAMMA,
    S_EPSN,
    S_EPSS,
    S_MODE,
    S_TN,
    S_TT,
    S_UPN,
    S_UPT,
)
from rockfrac.laws.cohesive_surface import _isv, _ratio, flow_direction, strengths
from rockfrac.laws.cohesive_system import _jump_weight, _scale, _system

MAX_ITER = 50  # local Newton iterations per solve
TOL_RES = 1.0e-12  # converged when the scaled residual norm is below this
TOL_STALL = 1.0e-9  # accepted if the line search stalls (round-off) below this

ST_ELASTIC = 0
ST_PLASTIC = 1
ST_NO_CONVERGENCE = -1
ST_UNLOAD = -2  # dgamma < 0 or inadmissible plastic direction
ST_SINGULAR = -3  # singular Jacobian or NaN


# --------------------------------------------------------------------------------------------
# dense solve and Newton
# --------------------------------------------------------------------------------------------


@inner
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


@kernel
def _norm(r):
    """Euclidean norm of the scaled (dimensionless) residual."""
    acc = 0.0
    for k in range(r.shape[0]):
        acc += r[k] * r[k]
    return math.sqrt(acc)


@inner
def _corner_limit(x0, dx0, sgn):
    """Largest step fraction (<= 1) keeping T_t on its side (sgn) of the corner T_t = 0."""
    if sgn != 0.0 and sgn * (x0 + dx0) <= 0.0:
        return 0.9 * abs(x0) / abs(dx0)
    return 1.0


@kernel
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


@inner
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


@kernel
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


@kernel
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


@inner
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


@inner
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
