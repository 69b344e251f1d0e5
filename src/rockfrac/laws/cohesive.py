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

from rockfrac.compiled import inner, kernel
from rockfrac.laws.cohesive_params import (
    MODE_ELASTIC,
    MODE_PLASTIC,
    N_STATE,
    P_CN,
    P_CT,
    P_TANPSI_P,
    S_DGAMMA,
    S_EPSN,
    S_EPSS,
    S_MODE,
    S_TN,
    S_TT,
)
from rockfrac.laws.cohesive_rescue import rescue_return
from rockfrac.laws.cohesive_solve import (
    CONVERGED,
    ST_ELASTIC,
    ST_PLASTIC,
    ST_SINGULAR,
    ST_UNLOAD,
    _commit,
    _frozen_return,
    _frozen_rows,  # noqa: F401  (re-exported: tests reach the kernels as cohesive.<name>)
    _newton,
    _tangent,
    workspace,
)
from rockfrac.laws.cohesive_surface import (
    _sign,
    elastic_tolerance,
    flow_direction,
    strengths,
    yield_function,
)
from rockfrac.laws.cohesive_system import (
    START_CROSSING,
    START_GIVEN,
    START_NONE,
    _jump_weight,  # noqa: F401  (re-exported, as above)
    _scale,
    _system,  # noqa: F401  (re-exported, as above)
    _work_start,
)
from rockfrac.threads import parallel_kernel

# --------------------------------------------------------------------------------------------
# EP form (Sect. 6.1, eq. 30-31)
# --------------------------------------------------------------------------------------------


@inner
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


@kernel
def return_map(du, s_old, comp, p, s_new, D):
    """Backward-Euler return (eq. 30-31) from T^tr = T_old + K^e du, K^e = diag(1/comp) [Pa/m].

    du (2,): local jump increment [m]; s_old/s_new: committed/new state (N_STATE,), T_old is
    s_old's traction; D (2, 2): consistent tangent dT/d(du) [Pa/m]. The EP CSE passes its
    penalty compliances; flow starts where the elastic path leaves the old surface.
    Returns 0 elastic, 1 plastic, < 0 failure (-1 no convergence, -2 dgamma < 0, -3 singular/NaN).
    """
    return rescued_step(du[0], du[1], s_old[S_TT], s_old[S_TN], s_old[S_TT], s_old[S_TN], np.int64(START_CROSSING),
                        comp[0], comp[1], s_old, p, s_new, D, workspace())


@kernel
def return_map_from(du, s_old, t_s, start, comp, p, s_new, D):
    """:func:`return_map` with the work rule's start-of-flow traction t_s (2,) [Pa] and its start kind.

    The RP CSE passes its augmentation (K^e = r I), T_old = lambda in s_old, and the committed
    traction with START_GIVEN (committed plastic) or START_NONE (see the module doc).
    """
    return return_step(du[0], du[1], s_old[S_TT], s_old[S_TN], t_s[0], t_s[1], start, comp[0], comp[1],
                       s_old, p, s_new, D, workspace())


@inner
def return_step(du_t, du_n, t_old_t, t_old_n, t_s_t, t_s_n, start, ct, cn, s_old, p, s_new, D, wk):
    """:func:`return_map_from` on scalars and a caller's :func:`workspace` (allocates nothing).

    (du_t, du_n) [m]: local jump increment; (t_old_t, t_old_n) [Pa]: the traction of the trial
    T^tr = T_old + K^e du, K^e = diag(1/ct, 1/cn); (t_s_t, t_s_n), start: the work rule's
    start-of-flow traction. s_old supplies the ISVs and plastic jumps (its traction is not read).
    Where the Newton from the frozen guess fails it fails (< 0): :func:`rescued_step` then solves the
    same return another way.
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


@inner
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
    return _finish(st, x, du, t_old, en_old, es_old, comp, p, ws, dws, s_old, s_new, D, wk)


@inner
def _finish(st, x, du, t_old, en_old, es_old, comp, p, ws, dws, s_old, s_new, D, wk):
    """After the local Newton (status st, solution x): the checks, the consistent tangent and the commit."""
    if st < 0:
        return st
    if x[4] < 0.0:
        return ST_UNLOAD
    if not _tangent(x, du, t_old, en_old, es_old, comp, p, ws, dws, D, wk, st == CONVERGED):
        return ST_SINGULAR
    gt, gn = flow_direction(x[0], x[1], x[2], x[3], p)
    _commit(x, x[4] * gt, x[4] * gn, s_old, s_new)
    return ST_PLASTIC


@inner
def rescued_step(du_t, du_n, t_old_t, t_old_n, t_s_t, t_s_n, start, ct, cn, s_old, p, s_new, D, wk):
    """:func:`return_step`, and where its Newton from the frozen guess fails, the same backward-Euler
    return from a bracketed guess or by continuation (:mod:`rockfrac.laws.cohesive_rescue`): the EP
    form's (du a jump increment). A separate entry so that only a run that needs it compiles it (the
    element kernels call it for their failed points: :func:`rockfrac.laws.mohr_coulomb_surface.
    ep_rescue_points`), and the RP form's too, its trial lambda + r h with K^e = r I
    (:func:`~rockfrac.laws.mohr_coulomb_surface.rp_rescue_points`)."""
    st = return_step(du_t, du_n, t_old_t, t_old_n, t_s_t, t_s_n, start, ct, cn, s_old, p, s_new, D, wk)
    if st >= 0:
        return st
    en_old, es_old = s_old[S_EPSN], s_old[S_EPSS]
    x, ws, dws, du, comp, t_old, t_s = wk[7], wk[8], wk[9], wk[10], wk[11], wk[12], wk[13]
    du[0], du[1] = du_t, du_n  # _plastic_step's set-up (the trial is outside: it returned < 0)
    comp[0], comp[1] = ct, cn
    t_old[0], t_old[1] = t_old_t, t_old_n
    t_s[0], t_s[1] = t_s_t, t_s_n
    st = rescue_return(x, du, t_old, t_s, start, en_old, es_old, comp, p, ws, dws, wk)
    return _finish(st, x, du, t_old, en_old, es_old, comp, p, ws, dws, s_old, s_new, D, wk)


@kernel
def ep_update(du, s_old, p, s_new, D):
    """EP return map (eq. 30-31) with the law's K^e = diag(kt, kn), for the local jump increment du [m];
    rescued where its Newton fails (:func:`rescued_step`)."""
    return ep_rescued_jump(du[0], du[1], s_old, p, s_new, D, workspace())


@inner
def ep_rescued_jump(du_t, du_n, s_old, p, s_new, D, wk):
    """:func:`ep_update_jump`, rescued where its Newton fails (:func:`rescued_step`)."""
    return rescued_step(du_t, du_n, s_old[S_TT], s_old[S_TN], s_old[S_TT], s_old[S_TN], np.int64(START_CROSSING),
                        p[P_CT], p[P_CN], s_old, p, s_new, D, wk)


@kernel
def ep_update_jump(du_t, du_n, s_old, p, s_new, D, wk):
    """:func:`ep_update` for the increment (du_t, du_n) [m] on a caller's :func:`workspace`."""
    return return_step(du_t, du_n, s_old[S_TT], s_old[S_TN], s_old[S_TT], s_old[S_TN], np.int64(START_CROSSING),
                       p[P_CT], p[P_CN], s_old, p, s_new, D, wk)


CHUNK = 256  # points per prange item: one workspace each, small enough to balance plastic clusters


@parallel_kernel(cost=0.5e-6)  # s per item, one thread (an estimate: no benchmark example calls it)
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


@inner
def _rp_admissible(du, p):
    """False if du cannot be dgamma g with dgamma > 0: g_n = tan psi >= 0 (zero iff tan psi_p = 0)."""
    if du[0] == 0.0 and du[1] == 0.0:
        return False
    if du[1] < 0.0:
        return False
    if p[P_TANPSI_P] > 0.0:
        return du[1] > 0.0
    return du[1] == 0.0


@inner
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


@inner
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


@inner
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


@kernel
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


@kernel
def rp_tangent_at(x, du, s_old, p, D):
    """D = dT/d(du) [Pa/m] of the RP local problem (eq. 34) evaluated at x (5,); 0 ok, -3 singular."""
    wk = workspace()
    _rp_work_start(du, s_old, p, wk)
    if _tangent(x, du, wk[12], s_old[S_EPSN], s_old[S_EPSS], wk[11], p, wk[8], wk[9], D, wk, False):
        return 0
    return ST_SINGULAR
