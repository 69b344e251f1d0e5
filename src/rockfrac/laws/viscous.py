"""Viscous (Duvaut-Lions) regularisation of any elasto-plastic traction law, EP form.

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
"""

from __future__ import annotations

import numba as nb
import numpy as np

from rockfrac.fem.interface import local_jump, local_jump_3d, pair_blocks_3d, pair_blocks_local
from rockfrac.threads import parallel_kernel

CHUNK = 256  # points per parallel task


@parallel_kernel(cost=0.3e-6)  # s per item, one thread (a few dozen flops per point)
def duvaut_lions_points(frame, weight, djump, s_old, s_new, d_new, a, kt, kn, dgamma_slot, mode_slot, t_bar,
                        fe, ke):
    """Regularise, in place, the law's return (s_new, d_new) at every point to the Duvaut-Lions update
    of the module doc, with blend factor a = r / (1 + r); t_bar (n, dim) receives the law's own
    tractions [Pa], fe (n, 2 dim) and ke (n, 2 dim, 2 dim) the node-pair blocks of the regularised
    ones. dim = frame.shape[1]: 2 (state tractions T_t, T_n) or 3 (T_t1, T_t2, T_n)."""
    n = frame.shape[0]
    m = s_old.shape[1]
    dim = frame.shape[1]
    chunks = (n + CHUNK - 1) // CHUNK
    for c in nb.prange(chunks):
        d = np.zeros((dim, dim))
        du = np.zeros(dim)
        k_el = np.full(dim, kt)  # the elastic stiffness diag(kt[, kt], kn)
        k_el[dim - 1] = kn
        for i in range(c * CHUNK, min(n, (c + 1) * CHUNK)):
            r = frame[i]
            if dim == 2:
                du[0], du[1] = local_jump(r, djump[i])
            else:
                du[0], du[1], du[2] = local_jump_3d(r, djump[i])
            for p in range(dim):
                t_bar[i, p] = s_new[i, p]
            for k in range(dim, m):
                if k == mode_slot:
                    continue
                if k == dgamma_slot:
                    s_new[i, k] = a * s_new[i, k]
                else:
                    s_new[i, k] = s_old[i, k] + a * (s_new[i, k] - s_old[i, k])
            for p in range(dim):
                tr = s_old[i, p] + k_el[p] * du[p]
                s_new[i, p] = tr + a * (t_bar[i, p] - tr)
                for q in range(dim):
                    d[p, q] = k_el[p] + a * (d_new[i, p, q] - k_el[p]) if p == q else a * d_new[i, p, q]
            for p in range(dim):
                for q in range(dim):
                    d_new[i, p, q] = d[p, q]
            if dim == 2:
                pair_blocks_local(r, weight[i], s_new[i, 0], s_new[i, 1], d, fe[i], ke[i])
            else:
                pair_blocks_3d(r, weight[i], s_new[i], d, fe[i], ke[i])
