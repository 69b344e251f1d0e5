"""Rescue of the cohesive return (eq. 31) where its Newton fails: a bracketed frozen return, then a
continuation in the jump increment. Local frame ``(t, n)``, tractions in Pa, jumps in m.

The local Newton of :mod:`rockfrac.laws.cohesive_solve` starts from the return with the strengths
frozen, itself solved by Newton in ``T_t``. Two situations defeat it:

* a trial far outside a surface that has (nearly) lost its strength: ``|T_t^tr| >> a_G`` while the
  solution has ``|T_t| << a_G`` (``g_t = T_t / sqrt(T_t^2 + a_G^2)`` is flat in ``T_t`` at the
  trial, so Newton cannot reach the return's ``dgamma``, which may be ``du_n / tan psi``);
* an increment that softens the surface through many decades in one step (a global iterate far
  from equilibrium with a stiff penalty), where the Newton path from the frozen guess leaves the
  line search no descent.

Neither changes the answer: both rescues only provide the starting point of the same backward-Euler
Newton, whose converged solution is unique when the stiffness exceeds the softening modulus.

1. **Bracketed frozen return.** With frozen strengths the return is one scalar equation in
   ``dgamma``: ``T_n = T_n^tr - k_n dgamma tan psi``, ``T_t`` solves ``T_t + k_t dgamma
   g_t(T_t) = T_t^tr``, and ``F(dgamma) = F(T_t, T_n)`` decreases monotonically from ``F > 0`` at
   ``dgamma = 0`` (``F_T . K^e g > 0``). Both roots are bracketed and found by safeguarded Newton;
   the inner one is solved in ``T_t`` where ``|T_t| > a_G`` and in ``g_t`` below, so neither
   variable is flat where it is used.
2. **Continuation.** The increment ``lambda du`` is grown from the elastic limit to ``lambda = 1``;
   each Newton starts from the previous converged state (or the bracketed frozen return, if that
   fails) and a failed one halves the growth.
"""

from __future__ import annotations

import math

import numpy as np

from rockfrac.compiled import inner, kernel
from rockfrac.laws.cohesive_solve import ST_NO_CONVERGENCE, _newton
from rockfrac.laws.cohesive_surface import _sign, strengths, yield_function
from rockfrac.laws.cohesive_system import _work_start

ROOT_ITER = 200  # safeguarded Newton iterations of one scalar root (bisection halves at worst)
MAX_CONTINUATION = 200  # continuation steps before the rescue gives up
MIN_GROWTH = 1.0e-8  # smallest continuation step in lambda


@inner
def _bracketed_step(x, f, df, lo, hi):
    """One safeguarded Newton step on an increasing residual f(x) whose root is bracketed by [lo, hi]:
    the bracket shrunk by the sign of f, then the Newton point if it is inside, else the midpoint.
    Returns (x_new, lo, hi, converged)."""
    if f > 0.0:
        hi = x
    else:
        lo = x
    x_new = x - f / df if df > 0.0 else 0.5 * (lo + hi)
    if not (lo < x_new < hi):
        x_new = 0.5 * (lo + hi)
    return x_new, lo, hi, abs(x_new - x) <= 4.0e-16 * abs(x) or hi - lo <= 4.0e-16 * abs(hi)


@kernel
def tangential_traction(tr, kappa, a_g):
    """|T_t| [Pa] solving ``t + kappa t / sqrt(t^2 + a_g^2) = tr`` for tr >= 0, kappa >= 0, a_g >= 0,
    with g_t = t / sqrt(t^2 + a_g^2) and d|T_t|/d kappa [m]: (t, g, dt_dkappa).

    The left side is increasing in t, so the root in [0, tr] is unique. Solved in t when it exceeds
    a_g (g_t near 1 there) and in g_t below (t is then a_g g / sqrt(1 - g^2), near linear).
    """
    if tr <= 0.0:
        return 0.0, 0.0, 0.0
    if not a_g > 0.0:  # degenerate hyperbola: g = 1 while t > 0, else t = 0 with g = tr / kappa
        if tr > kappa:
            return tr - kappa, 1.0, -1.0
        return 0.0, tr / kappa, 0.0
    if a_g + kappa / math.sqrt(2.0) < tr:  # t > a_g: phi(t) = t + kappa t / r - tr, concave increasing
        lo, hi = a_g, tr
        t = tr
        for _ in range(ROOT_ITER):
            r = math.sqrt(t * t + a_g * a_g)
            t, lo, hi, done = _bracketed_step(t, t + kappa * t / r - tr, 1.0 + kappa * a_g * a_g / (r * r * r), lo, hi)
            if done:
                break
        r = math.sqrt(t * t + a_g * a_g)
        return t, t / r, -(t / r) / (1.0 + kappa * a_g * a_g / (r * r * r))
    # t <= a_g: psi(g) = a_g g / sqrt(1 - g^2) + kappa g - tr, convex increasing on [0, 1/sqrt(2)]
    lo, hi = 0.0, 1.0 / math.sqrt(2.0)
    g = min(tr / (a_g + kappa), hi)
    for _ in range(ROOT_ITER):
        q = math.sqrt(1.0 - g * g)
        g, lo, hi, done = _bracketed_step(g, a_g * g / q + kappa * g - tr, a_g / (q * q * q) + kappa, lo, hi)
        if done:
            break
    q = math.sqrt(1.0 - g * g)
    dg_dk = -g / (a_g / (q * q * q) + kappa)
    return a_g * g / q, g, a_g / (q * q * q) * dg_dk


@inner
def _frozen_yield(dg, tt_tr, tn_tr, kt, kn, chi, c, tphi, tpsi):
    """F [Pa] and dF/d dgamma [Pa/m] of the frozen return at dgamma, with (T_t, T_n) [Pa]."""
    a_g = c - chi * tpsi
    a_f = c - chi * tphi
    sg = _sign(tt_tr)
    t, _, dt_dk = tangential_traction(abs(tt_tr), kt * dg, abs(a_g))
    tn = tn_tr - kn * dg * tpsi
    r_f = math.sqrt(t * t + a_f * a_f)
    f = r_f - c + tn * tphi
    dt = (t / r_f if r_f > 0.0 else 0.0) * kt * dt_dk
    return f, dt - tphi * kn * tpsi, sg * t, tn


@kernel
def bracketed_frozen_return(x, du, t_old, comp, p):
    """The return with the strengths frozen at x's ISVs, by bracketing its dgamma; x = (T_t, T_n,
    eps_n, eps_s, dgamma) is overwritten with it. False if no dgamma > 0 reaches F = 0 (no dilation
    and a tension the surface cannot return) or the trial is inside."""
    chi, c, tphi, tpsi = strengths(x[2], x[3], p)
    kt, kn = 1.0 / comp[0], 1.0 / comp[1]
    tt_tr = t_old[0] + du[0] * kt
    tn_tr = t_old[1] + du[1] * kn
    f0 = _frozen_yield(0.0, tt_tr, tn_tr, kt, kn, chi, c, tphi, tpsi)[0]
    if not f0 > 0.0:
        return False
    scale = max(abs(tt_tr) / kt + abs(tn_tr) / kn, 1.0e-300)  # dgamma of a return to T = 0, roughly
    lo, hi = 0.0, scale
    for _ in range(2100):
        if _frozen_yield(hi, tt_tr, tn_tr, kt, kn, chi, c, tphi, tpsi)[0] < 0.0:
            break
        lo = hi
        hi *= 2.0
        if not hi < np.inf:
            return False
    else:
        return False
    dg = 0.5 * (lo + hi)
    for _ in range(ROOT_ITER):
        f, df, _, _ = _frozen_yield(dg, tt_tr, tn_tr, kt, kn, chi, c, tphi, tpsi)
        dg, lo, hi, done = _bracketed_step(dg, -f, -df, lo, hi)  # F decreases in dgamma
        if done:
            break
    _, _, tt, tn = _frozen_yield(dg, tt_tr, tn_tr, kt, kn, chi, c, tphi, tpsi)
    x[0], x[1], x[4] = tt, tn, dg
    return True


@inner
def _solve_at(lam, x, du, t_old, t_s, start, en_old, es_old, comp, p, sub_du, ws, dws, wk):
    """Newton of the return for the increment lam du from x (kept as found if it fails), with its own
    work-rule start terms; the status of :func:`rockfrac.laws.cohesive_solve._newton`."""
    sub_du[0], sub_du[1] = lam * du[0], lam * du[1]
    _work_start(t_s, sub_du, comp, en_old, es_old, p, start, ws, dws)
    sgn = _sign(t_old[0] + sub_du[0] / comp[0])
    if sgn != 0.0 and x[0] * sgn <= 0.0:
        x[0] = sgn * 1.0e-6 * max(abs(x[0]), 1.0)
    return _newton(x, sub_du, t_old, en_old, es_old, comp, p, ws, sgn, wk)


@kernel
def rescue_return(x, du, t_old, t_s, start, en_old, es_old, comp, p, ws, dws, wk):
    """The backward-Euler return (eq. 31) where its Newton from the frozen guess failed: x (5,) gets
    the solution; ws, dws get the work rule's terms of du. Returns the final Newton's status (its wk
    jac is the Jacobian at x when CONVERGED) or ST_NO_CONVERGENCE."""
    x0 = np.empty(5)
    x_last = np.empty(5)
    sub_du = np.empty(2)
    w_s = np.empty(3)
    dw_s = np.empty((2, 2))
    x0[0], x0[1] = t_old[0] + du[0] / comp[0], t_old[1] + du[1] / comp[1]
    x0[2], x0[3], x0[4] = en_old, es_old, 0.0
    for k in range(5):  # 1. the bracketed frozen return as the Newton's start
        x[k] = x0[k]
    if bracketed_frozen_return(x, du, t_old, comp, p):
        st = _solve_at(1.0, x, du, t_old, t_s, start, en_old, es_old, comp, p, sub_du, ws, dws, wk)
        if st > 0 and x[4] >= 0.0:
            return st
    # 2. continuation from the elastic limit: lam_lo du is inside the old surface, lam_hi du outside
    lam_lo, lam_hi = 0.0, 1.0
    for _ in range(60):
        mid = 0.5 * (lam_lo + lam_hi)
        if yield_function(t_old[0] + mid * du[0] / comp[0], t_old[1] + mid * du[1] / comp[1], en_old, es_old,
                          p) > 0.0:
            lam_hi = mid
        else:
            lam_lo = mid
    for k in range(5):
        x_last[k] = x0[k]
    x_last[0], x_last[1] = t_old[0] + lam_hi * du[0] / comp[0], t_old[1] + lam_hi * du[1] / comp[1]
    lam = lam_lo
    step = max(lam_hi - lam_lo, 1.0e-3 * (1.0 - lam_lo))
    for _ in range(MAX_CONTINUATION):
        target = min(lam + step, 1.0)
        last = target == 1.0
        for k in range(5):
            x[k] = x_last[k]
        st = _solve_at(target, x, du, t_old, t_s, start, en_old, es_old, comp, p, sub_du,
                       ws if last else w_s, dws if last else dw_s, wk)
        if not (st > 0 and x[4] >= 0.0):  # the bracketed frozen return at this lam, then smaller steps
            for k in range(5):
                x[k] = x_last[k]
            x[0] = t_old[0] + target * du[0] / comp[0]
            x[1] = t_old[1] + target * du[1] / comp[1]
            x[4] = 0.0
            sub_du[0], sub_du[1] = target * du[0], target * du[1]
            if bracketed_frozen_return(x, sub_du, t_old, comp, p):
                st = _solve_at(target, x, du, t_old, t_s, start, en_old, es_old, comp, p, sub_du,
                               ws if last else w_s, dws if last else dw_s, wk)
        if st > 0 and x[4] >= 0.0:
            if last:
                return st
            for k in range(5):
                x_last[k] = x[k]
            lam = target
            step *= 2.0
        else:
            step *= 0.25
            if step < MIN_GROWTH * max(1.0 - lam, 1.0e-300):
                break
    return ST_NO_CONVERGENCE


__all__ = ["bracketed_frozen_return", "rescue_return", "tangential_traction"]
