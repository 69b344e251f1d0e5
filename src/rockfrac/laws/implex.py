"""IMPL-EX integration of any elasto-plastic traction law (Oliver, Huespe & Cante 2008), EP form.

The implicit step (the law's own return map at the converged jump) updates the state; the traction
that enters equilibrium is the explicit one, with the plastic jump extrapolated linearly from the
last two committed states:

    T_ex = T_n + K ([[u]] increment - r (u_p,n - u_p,n-1)),   r = dt_{n+1} / dt_n,

local frame (t, n), K = diag(kt, kn) the penalty [Pa/m], u_p the plastic jump [m] (the common state
slots of :mod:`rockfrac.laws.traction_law`, so every law gets it). T_ex is linear in the jump with
the constant tangent K: a step has no active set to find and no return to converge, so Newton
takes one iteration per step whatever yields or softens, and the tangent is symmetric positive
definite. The price is an error of first order in the step size against the implicit solution
(tested); dt is the step's increment of its control parameter (load factor or path measure).
"""

from __future__ import annotations

import numba as nb
import numpy as np

from rockfrac.fem.interface import local_jump, pair_blocks_local
from rockfrac.laws.traction_law import S_TN, S_TT, S_UPN, S_UPT
from rockfrac.threads import parallel_kernel

CHUNK = 256  # points per parallel task


@parallel_kernel(cost=0.2e-6)  # s per item, one thread (a few flops per point)
def implex_points(frame, weight, djump, s_old, up_prev, ratio, kt, kn, t_ex, fe, ke):
    """Explicit tractions t_ex (n, 2) [Pa] and element blocks fe (n, 4), ke (n, 4, 4) at every point
    (module doc): djump (n, 2) the global jump increment of the step, s_old the committed states,
    up_prev (n, 2) the committed plastic jumps one step earlier, ratio = dt_{n+1} / dt_n."""
    n = frame.shape[0]
    chunks = (n + CHUNK - 1) // CHUNK
    for c in nb.prange(chunks):
        d = np.zeros((2, 2))  # the local tangent K, once per chunk
        d[0, 0] = kt
        d[1, 1] = kn
        for i in range(c * CHUNK, min(n, (c + 1) * CHUNK)):
            r = frame[i]
            du_t, du_n = local_jump(r, djump[i])
            ex_t = ratio * (s_old[i, S_UPT] - up_prev[i, 0])
            ex_n = ratio * (s_old[i, S_UPN] - up_prev[i, 1])
            t_ex[i, 0] = s_old[i, S_TT] + kt * (du_t - ex_t)
            t_ex[i, 1] = s_old[i, S_TN] + kn * (du_n - ex_n)
            pair_blocks_local(r, weight[i], t_ex[i, 0], t_ex[i, 1], d, fe[i], ke[i])
