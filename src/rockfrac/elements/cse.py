"""Zero-thickness cohesive surface elements with nodal integration (paper Sect. 6.1, 6.2).

Each integration point is a (minus, plus) node pair. The jump is u(+) - u(-) in the global
frame, rotated to the local ``(t, n)`` frame by the point's rotation R (rows t, n); the local
traction T from the law is rotated back, T_g = R^T T, and enters the weak form (5) as
``+ int [[w]] . T ds``.

At the start of a step (zero jump increment) a point that was plastic in the committed state
keeps its committed traction and consistent tangent, so the first Newton iteration of a
softening step predicts continued plastic flow instead of an elastic (or rigid) response.
"""

from __future__ import annotations

import numba as nb

from rockfrac.laws.cohesive import (
    CHUNK,
    START_GIVEN,
    START_NONE,
    ep_update_jump,
    return_step,
    workspace,
)
from rockfrac.laws.cohesive_params import MODE_PLASTIC, S_DGAMMA, S_MODE, S_TN, S_TT


@nb.njit(cache=True, inline="always")
def _pair_blocks_local(r, w, t_t, t_n, d, fe, ke):
    """Force and stiffness of one node pair, dofs (minus x, minus y, plus x, plus y), from the local
    traction (t_t, t_n) and tangent d: global T_g = R^T t, D_g = R^T d R; on scalars, no temporaries."""
    tg0 = r[0, 0] * t_t + r[1, 0] * t_n
    tg1 = r[0, 1] * t_t + r[1, 1] * t_n
    fe[0] = -w * tg0
    fe[1] = -w * tg1
    fe[2] = w * tg0
    fe[3] = w * tg1
    for i in range(2):
        for j in range(2):
            s = 0.0
            for a in range(2):
                for b in range(2):
                    s += r[a, i] * d[a, b] * r[b, j]
            k = w * s
            ke[i, j] = k
            ke[i, 2 + j] = -k
            ke[2 + i, j] = -k
            ke[2 + i, 2 + j] = k


@nb.njit(cache=True, inline="always")
def _keep_committed(s_old, d_old, s_new, d_new):
    """Start of a step at a committed plastic point: same traction, committed tangent."""
    s_new[:] = s_old
    s_new[S_DGAMMA] = 0.0
    d_new[:, :] = d_old


@nb.njit(cache=True, parallel=True)
def ep_points(frame, weight, djump, s_old, d_old, p, s_new, d_new, fe, ke, status):
    """EP CSE at all points: local return map (paper eq. 31) and element blocks.

    djump: (n, 2) global jump increment since the committed state [m]; d_old (n, 2, 2) the
    committed tangents; fe (n, 4), ke (n, 4, 4).
    """
    n = frame.shape[0]
    for c in nb.prange((n + CHUNK - 1) // CHUNK):
        wk = workspace()  # one scratch per chunk: a plastic point allocates nothing
        for i in range(c * CHUNK, min(n, (c + 1) * CHUNK)):
            r = frame[i]
            du_t = r[0, 0] * djump[i, 0] + r[0, 1] * djump[i, 1]
            du_n = r[1, 0] * djump[i, 0] + r[1, 1] * djump[i, 1]
            if du_t == 0.0 and du_n == 0.0 and s_old[i, S_MODE] == MODE_PLASTIC:
                _keep_committed(s_old[i], d_old[i], s_new[i], d_new[i])
                status[i] = 1
            else:
                status[i] = ep_update_jump(du_t, du_n, s_old[i], p, s_new[i], d_new[i], wk)
            _pair_blocks_local(r, weight[i], s_new[i, S_TT], s_new[i, S_TN], d_new[i], fe[i], ke[i])


@nb.njit(cache=True, inline="always")
def _rp_point(i, frame, weight, djump, lam, aug, eps, pinned, s_old, d_old, mode_prev, p, s_new, d_new, fe, ke,
              status, switched, wk):
    """Point i of :func:`rp_points`."""
    r = frame[i]
    w = weight[i]
    h_t = r[0, 0] * djump[i, 0] + r[0, 1] * djump[i, 1]
    h_n = r[1, 0] * djump[i, 0] + r[1, 1] * djump[i, 1]
    if h_t == 0.0 and h_n == 0.0 and s_old[i, S_MODE] == MODE_PLASTIC and not pinned[i]:
        _keep_committed(s_old[i], d_old[i], s_new[i], d_new[i])
        status[i] = 1
    elif pinned[i]:  # the constrained branch of eq. (33): T = lambda + r h, D = r I
        s_new[i, :] = s_old[i, :]
        s_new[i, S_TT] = r[0, 0] * lam[i, 0] + r[0, 1] * lam[i, 1] + aug * h_t
        s_new[i, S_TN] = r[1, 0] * lam[i, 0] + r[1, 1] * lam[i, 1] + aug * h_n
        s_new[i, S_DGAMMA] = 0.0
        s_new[i, S_MODE] = 0.0
        d_new[i, :, :] = 0.0
        d_new[i, 0, 0] = aug
        d_new[i, 1, 1] = aug
        status[i] = 0
    else:
        lam_t = r[0, 0] * lam[i, 0] + r[0, 1] * lam[i, 1]  # T_old := lambda (local frame)
        lam_n = r[1, 0] * lam[i, 0] + r[1, 1] * lam[i, 1]
        comp = 1.0 / aug
        # trial lambda + r h: elastic, or the return; the work rule's flow starts at the committed
        # traction of a committed plastic point
        start = START_GIVEN if s_old[i, S_MODE] == MODE_PLASTIC else START_NONE
        status[i] = return_step(h_t, h_n, lam_t, lam_n, s_old[i, S_TT], s_old[i, S_TN], start, comp, comp,
                                s_old[i], p, s_new[i], d_new[i], wk)
    switched[i] = 1 if s_new[i, S_MODE] != mode_prev[i] else 0
    fi = fe[i]
    ki = ke[i]
    _pair_blocks_local(r, w, s_new[i, S_TT], s_new[i, S_TN], d_new[i], fi, ki)
    for a in range(2):
        tg_a = r[0, a] * s_new[i, S_TT] + r[1, a] * s_new[i, S_TN]
        fi[4 + a] = w * (tg_a - lam[i, a])
        for b in range(2):
            kab = ki[a, b]  # w R^T D R, as _pair_blocks_local wrote it
            # dT/dlambda = D / r; dT/d[[u]] = D; d(T - lambda)/dlambda = D / r - I
            ki[a, 4 + b] = -kab / aug
            ki[2 + a, 4 + b] = kab / aug
            ki[4 + a, b] = -kab
            ki[4 + a, 2 + b] = kab
            ki[4 + a, 4 + b] = kab / aug - (w if a == b else 0.0)
    if eps[i] > 0.0 and s_new[i, S_MODE] != MODE_PLASTIC:
        for a in range(2):  # least circulation of junction multipliers (CohesiveRP)
            lam_n = r[0, a] * s_old[i, S_TT] + r[1, a] * s_old[i, S_TN]
            fi[4 + a] -= eps[i] * w * (lam[i, a] - lam_n)
            ki[4 + a, 4 + a] -= eps[i] * w


@nb.njit(cache=True, parallel=True)
def rp_points(frame, weight, djump, lam, aug, eps, pinned, s_old, d_old, mode_prev, p, s_new, d_new, fe, ke,
              status, switched):
    """RP CSE at all points: augmented Lagrangian (paper eq. 32-33) with the law's return map.

    Element dofs (n, 6): (minus x, minus y, plus x, plus y, lambda x, lambda y); lam (n, 2)
    global-frame multipliers [Pa], aug the augmentation r [Pa/m], djump = h (eq. 32) [m].
    The law is evaluated at the augmented trial traction T^tr = lambda + r h: below the yield
    surface T = lambda + r h (eq. 33, the constrained state); above it the backward-Euler return
    T = T^tr - r dgamma dG/dT (the paper's first-plastic-step predictor with K^e = r I, here used
    in every iteration). The multiplier rows w (T - lambda) = w r (h - Delta[[u^p]]) enforce
    [[u]]_{n+1} - [[u]]_n = Delta[[u^p]] exactly at convergence, where T = lambda: the converged
    state solves eq. (34) and the surface is rigid until F(lambda) = 0.
    mode_prev: mode of each point in the previous iterate (a change counts as a switch). eps (n,):
    perturbed-Lagrangian weight of constrained junction pairs (0 elsewhere), see CohesiveRP.
    pinned (n,): held constrained in this iteration whatever their trial (active-set pinning, see
    CohesiveRP).
    """
    n = frame.shape[0]
    for c in nb.prange((n + CHUNK - 1) // CHUNK):
        wk = workspace()  # one scratch per chunk: a plastic point allocates nothing
        for i in range(c * CHUNK, min(n, (c + 1) * CHUNK)):
            _rp_point(i, frame, weight, djump, lam, aug, eps, pinned, s_old, d_old, mode_prev, p, s_new, d_new,
                      fe, ke, status, switched, wk)
