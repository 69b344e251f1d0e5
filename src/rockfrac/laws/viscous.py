"""Viscous (Duvaut-Lions) regularisation of any elasto-plastic traction law, EP form.

The overstress relaxes towards the rate-independent answer with a relaxation time eta [the
pseudo-time of history.csv's ``time``: one load-controlled stage = 1]. Backward Euler over a step of
pseudo-time dt (Simo & Hughes 1998, Sect. 2.7), with r = dt / eta and a = r / (1 + r):

    T   = T_tr + a (T_bar - T_tr)          T_tr = T_n + K d[[u]] (the elastic trial)
    q   = q_n + a (q_bar - q_n)            every other state slot (plastic jump, the law's work
                                           variables); the step's dgamma is a dgamma_bar
    D   = K + a (D_bar - K)                the consistent tangent dT/d[[u]]

local frame (t, n), K = diag(kt, kn) [Pa/m], (T_bar, q_bar, D_bar) the law's own return map from
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

from rockfrac.fem.interface import local_jump, pair_blocks_local
from rockfrac.laws.traction_law import S_TN, S_TT
from rockfrac.threads import parallel_kernel

CHUNK = 256  # points per parallel task


@parallel_kernel(cost=0.3e-6)  # s per item, one thread (a few dozen flops per point)
def duvaut_lions_points(frame, weight, djump, s_old, s_new, d_new, a, kt, kn, dgamma_slot, mode_slot, t_bar,
                        fe, ke):
    """Regularise, in place, the law's return (s_new, d_new) at every point to the Duvaut-Lions update
    of the module doc, with blend factor a = r / (1 + r); t_bar (n, 2) receives the law's own
    tractions [Pa], fe (n, 4) and ke (n, 4, 4) the node-pair blocks of the regularised ones."""
    n = frame.shape[0]
    m = s_old.shape[1]
    chunks = (n + CHUNK - 1) // CHUNK
    for c in nb.prange(chunks):
        d = np.zeros((2, 2))
        for i in range(c * CHUNK, min(n, (c + 1) * CHUNK)):
            r = frame[i]
            du_t, du_n = local_jump(r, djump[i])
            tr_t = s_old[i, S_TT] + kt * du_t
            tr_n = s_old[i, S_TN] + kn * du_n
            t_bar[i, 0] = s_new[i, S_TT]
            t_bar[i, 1] = s_new[i, S_TN]
            for k in range(m):
                if k == S_TT or k == S_TN or k == mode_slot:
                    continue
                if k == dgamma_slot:
                    s_new[i, k] = a * s_new[i, k]
                else:
                    s_new[i, k] = s_old[i, k] + a * (s_new[i, k] - s_old[i, k])
            s_new[i, S_TT] = tr_t + a * (t_bar[i, 0] - tr_t)
            s_new[i, S_TN] = tr_n + a * (t_bar[i, 1] - tr_n)
            d[0, 0] = kt + a * (d_new[i, 0, 0] - kt)
            d[0, 1] = a * d_new[i, 0, 1]
            d[1, 0] = a * d_new[i, 1, 0]
            d[1, 1] = kn + a * (d_new[i, 1, 1] - kn)
            for p in range(2):
                for q in range(2):
                    d_new[i, p, q] = d[p, q]
            pair_blocks_local(r, weight[i], s_new[i, S_TT], s_new[i, S_TN], d, fe[i], ke[i])
