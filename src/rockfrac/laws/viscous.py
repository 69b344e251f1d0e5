"""Viscous (Duvaut-Lions) regularisation of any elasto-plastic traction law, EP and RP forms.

The overstress relaxes towards the rate-independent answer with a relaxation time eta [the
pseudo-time of history.csv's ``time``: one load-controlled stage = 1]. Backward Euler over a step of
pseudo-time dt (Simo & Hughes 1998, Sect. 2.7), with r = dt / eta and a = r / (1 + r):

    T   = T_tr + a (T_bar - T_tr)          T_tr = T_n + K d[[u]] (the elastic trial)
    q   = q_n + a (q_bar - q_n)            every other state slot (plastic jump, the law's work
                                           variables); the step's dgamma is a dgamma_bar
    D   = K + a (D_bar - K)                the consistent tangent dT/d[[u]]

local frame (t, n), K = diag(kt, kn) [Pa/m] (3D: (t1, t2, n), K = diag(kt, kt, kn)), (T_bar, q_bar,
D_bar) the law's own return map from
the committed state (its implicit EP update). a -> 1 (eta -> 0) is the law itself; a small a keeps a
step near the elastic trial, so load-controlled steps through a snap-back converge, at the price of
an extra dissipation that each group reports: the overstress T - T_bar times the plastic jump's
increment, whose end-of-step value (T - T_bar) . (u_p - u_p,n) >= 0 per unit area, since
T - T_bar = K (u_p_bar - u_p,n) / (1 + r) and u_p - u_p,n = a (u_p_bar - u_p,n) (the groups
integrate it by the trapezoidal rule, like their work account).

RP form (augmented multipliers, paper eq. 32-34): the same update with the augmented trial
T_tr = lambda + r h and K = r I (r the augmentation [Pa/m]). The multiplier row w (T - lambda) = 0
then gives r h = a / (1 - a) (lambda - T_bar): the plastic jump's rate is the overstress over
eta r, as for EP with kn = kt = r, and a point held shut on a loop (h = 0) sits on its yield surface
without overstress. A constrained point is untouched (T_bar = T_tr).
"""

from __future__ import annotations

import numba as nb
import numpy as np

from rockfrac.compiled import inner
from rockfrac.fem.interface import (
    junction_rows,
    local_jump,
    local_jump_3d,
    multiplier_rows,
    multiplier_rows_3d,
    pair_blocks_3d,
    pair_blocks_local,
)
from rockfrac.laws.traction_law import MODE_PLASTIC
from rockfrac.threads import parallel_kernel

CHUNK = 256  # points per parallel task


@inner
def to_local(r, v, out):
    """out (dim,) = the local components of the global vector v (dim,), dim 2 (t, n) or 3 (t1, t2, n)."""
    if out.shape[0] == 2:
        out[0], out[1] = local_jump(r, v)
    else:
        out[0], out[1], out[2] = local_jump_3d(r, v)


@inner
def blend_point(s_old, s_new, d_new, tr, k_el, a, dgamma_slot, mode_slot, t_bar, d):
    """One point's Duvaut-Lions update of the module doc, in place on (s_new, d_new): the law's own
    return (s_new, d_new) blended with the trial tractions tr (dim,) of stiffness diag(k_el); t_bar
    (dim,) receives the law's tractions, d (dim, dim) the blended tangent."""
    dim = tr.shape[0]
    for p in range(dim):
        t_bar[p] = s_new[p]
    for k in range(dim, s_old.shape[0]):
        if k == mode_slot:
            continue
        if k == dgamma_slot:
            s_new[k] = a * s_new[k]
        else:
            s_new[k] = s_old[k] + a * (s_new[k] - s_old[k])
    for p in range(dim):
        s_new[p] = tr[p] + a * (t_bar[p] - tr[p])
        for q in range(dim):
            d[p, q] = k_el[p] + a * (d_new[p, q] - k_el[p]) if p == q else a * d_new[p, q]
    for p in range(dim):
        for q in range(dim):
            d_new[p, q] = d[p, q]


@parallel_kernel(cost=0.3e-6)  # s per item, one thread (a few dozen flops per point)
def duvaut_lions_points(frame, weight, djump, s_old, s_new, d_new, a, kt, kn, dgamma_slot, mode_slot, t_bar,
                        fe, ke):
    """Regularise, in place, the law's return (s_new, d_new) at every point to the Duvaut-Lions update
    of the module doc, with blend factor a = r / (1 + r); t_bar (n, dim) receives the law's own
    tractions [Pa], fe (n, 2 dim) and ke (n, 2 dim, 2 dim) the node-pair blocks of the regularised
    ones. dim = frame.shape[1]: 2 (state tractions T_t, T_n) or 3 (T_t1, T_t2, T_n)."""
    n = frame.shape[0]
    dim = frame.shape[1]
    chunks = (n + CHUNK - 1) // CHUNK
    for c in nb.prange(chunks):
        d = np.zeros((dim, dim))
        du = np.zeros(dim)
        tr = np.zeros(dim)
        k_el = np.full(dim, kt)  # the elastic stiffness diag(kt[, kt], kn)
        k_el[dim - 1] = kn
        for i in range(c * CHUNK, min(n, (c + 1) * CHUNK)):
            r = frame[i]
            to_local(r, djump[i], du)
            for p in range(dim):
                tr[p] = s_old[i, p] + k_el[p] * du[p]
            blend_point(s_old[i], s_new[i], d_new[i], tr, k_el, a, dgamma_slot, mode_slot, t_bar[i], d)
            if dim == 2:
                pair_blocks_local(r, weight[i], s_new[i, 0], s_new[i, 1], d, fe[i], ke[i])
            else:
                pair_blocks_3d(r, weight[i], s_new[i], d, fe[i], ke[i])


@parallel_kernel(cost=0.4e-6)  # s per item, one thread: the EP update's and the multiplier rows
def duvaut_lions_rp_points(frame, weight, djump, lam, aug, eps, s_old, s_new, d_new, a, dgamma_slot, mode_slot,
                           t_bar, fe, ke):
    """The RP form's Duvaut-Lions update (module doc) of the law's augmented return (s_new, d_new), in
    place: trial lambda + r h (lam (n, dim) global multipliers [Pa], aug = r [Pa/m]); fe (n, 3 dim) and
    ke (n, 3 dim, 3 dim) the pair's blocks with the multiplier rows (and the junction term of a
    constrained junction pair, eps > 0), as the RP kernels write them."""
    n = frame.shape[0]
    dim = frame.shape[1]
    chunks = (n + CHUNK - 1) // CHUNK
    for c in nb.prange(chunks):
        d = np.zeros((dim, dim))
        h = np.zeros(dim)
        ll = np.zeros(dim)
        tr = np.zeros(dim)
        k_el = np.full(dim, aug)
        for i in range(c * CHUNK, min(n, (c + 1) * CHUNK)):
            r = frame[i]
            to_local(r, djump[i], h)
            to_local(r, lam[i], ll)
            for p in range(dim):
                tr[p] = ll[p] + aug * h[p]
            blend_point(s_old[i], s_new[i], d_new[i], tr, k_el, a, dgamma_slot, mode_slot, t_bar[i], d)
            junction = eps[i] > 0.0 and s_new[i, mode_slot] != MODE_PLASTIC
            if dim == 2:
                pair_blocks_local(r, weight[i], s_new[i, 0], s_new[i, 1], d, fe[i], ke[i])
                multiplier_rows(r, weight[i], s_new[i, 0], s_new[i, 1], lam[i], aug, fe[i], ke[i])
                if junction:
                    junction_rows(weight[i], eps[i], ke[i], 2)
            else:
                pair_blocks_3d(r, weight[i], s_new[i], d, fe[i], ke[i])
                multiplier_rows_3d(r, weight[i], s_new[i], lam[i], aug, eps[i], junction, fe[i], ke[i])
