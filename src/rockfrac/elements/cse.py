"""Zero-thickness cohesive surface elements with nodal integration (paper Sect. 6.1, 6.2).

Each integration point is a (minus, plus) node pair. The jump is u(+) - u(-) in the global
frame, rotated to the local ``(t, n)`` frame by the point's rotation R (rows t, n); the local
traction T from the law is rotated back, T_g = R^T T, and enters the weak form (5) as
``+ int [[w]] . T ds``.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from rockfrac.laws.cohesive import ep_update, rp_predictor, rp_tangent_at, rp_update, yield_function
from rockfrac.laws.cohesive_params import (
    N_STATE,
    P_C_P,
    P_CHI_P,
    S_DGAMMA,
    S_EPSN,
    S_EPSS,
    S_MODE,
    S_TN,
    S_TT,
    S_UPN,
    S_UPT,
)


@nb.njit(cache=True, inline="always")
def _rotate_back(r: np.ndarray, t: np.ndarray, d: np.ndarray, tg: np.ndarray, dg: np.ndarray) -> None:
    """Global traction tg = R^T t and tangent dg = R^T d R."""
    for i in range(2):
        tg[i] = r[0, i] * t[0] + r[1, i] * t[1]
    for i in range(2):
        for j in range(2):
            s = 0.0
            for a in range(2):
                for b in range(2):
                    s += r[a, i] * d[a, b] * r[b, j]
            dg[i, j] = s


@nb.njit(cache=True, inline="always")
def _pair_blocks(w: float, tg: np.ndarray, dg: np.ndarray, fe: np.ndarray, ke: np.ndarray) -> None:
    """Force and stiffness of one node pair: dofs (minus x, minus y, plus x, plus y)."""
    for i in range(2):
        fe[i] = -w * tg[i]
        fe[2 + i] = w * tg[i]
        for j in range(2):
            k = w * dg[i, j]
            ke[i, j] = k
            ke[i, 2 + j] = -k
            ke[2 + i, j] = -k
            ke[2 + i, 2 + j] = k


@nb.njit(cache=True, parallel=True)
def ep_points(frame, weight, djump, s_old, p, s_new, d_new, fe, ke, status):
    """EP CSE at all points: local return map (paper eq. 31) and element blocks.

    djump: (n, 2) global jump increment since the committed state [m]; fe (n, 4), ke (n, 4, 4).
    """
    for i in nb.prange(frame.shape[0]):
        r = frame[i]
        du = np.empty(2)
        du[0] = r[0, 0] * djump[i, 0] + r[0, 1] * djump[i, 1]
        du[1] = r[1, 0] * djump[i, 0] + r[1, 1] * djump[i, 1]
        status[i] = ep_update(du, s_old[i], p, s_new[i], d_new[i])
        tg = np.empty(2)
        dg = np.empty((2, 2))
        _rotate_back(r, s_new[i, S_TT : S_TN + 1], d_new[i], tg, dg)
        _pair_blocks(weight[i], tg, dg, fe[i], ke[i])


@nb.njit(cache=True, parallel=True)
def rp_points(frame, weight, djump, lam, aug, s_old, s_prev, d_old, p, s_new, d_new, fe, ke, status, switched):
    """RP CSE at all points (paper eq. 32-34): constrained points carry multipliers, plastic ones
    the traction of the local problem (34).

    Element dofs (n, 6): (minus x, minus y, plus x, plus y, lambda x, lambda y); lam (n, 2) are the
    global-frame multipliers, aug the augmentation r [Pa/m]. Multiplier rows are in force units:
    r w h at a constrained point (eq. 33 scaled by r), w (lambda - T_g) at a plastic one, so lambda tracks the traction and a point that unloads returns to
    the constrained state with its current traction.
    """
    tol = 1e-9 * max(p[P_C_P], p[P_CHI_P], 1.0)
    for i in nb.prange(frame.shape[0]):
        r = frame[i]
        w = weight[i]
        h = djump[i]
        du = np.empty(2)
        du[0] = r[0, 0] * h[0] + r[0, 1] * h[1]
        du[1] = r[1, 0] * h[0] + r[1, 1] * h[1]
        s_new[i, :] = s_old[i, :]
        d = d_new[i]
        x = np.empty(5)
        plastic = False
        switched[i] = 0
        status[i] = 0
        if s_prev[i, S_MODE] == 0.0:
            t_lam = np.empty(2)
            t_lam[0] = r[0, 0] * lam[i, 0] + r[0, 1] * lam[i, 1]
            t_lam[1] = r[1, 0] * lam[i, 0] + r[1, 1] * lam[i, 1]
            if yield_function(t_lam[0], t_lam[1], s_old[i, S_EPSN], s_old[i, S_EPSS], p) > tol:
                # first plastic iteration: Delta gamma from the K^e predictor (Sect. 6.2)
                if rp_predictor(t_lam, s_old[i], p, x) < 0:
                    status[i] = -1
                    continue
                rp_tangent_at(x, du, s_old[i], p, d)
                s_new[i, S_TT] = x[0]
                s_new[i, S_TN] = x[1]
                s_new[i, S_EPSN] = x[2]
                s_new[i, S_EPSS] = x[3]
                s_new[i, S_DGAMMA] = x[4]
                s_new[i, S_UPT] = s_old[i, S_UPT] + du[0]
                s_new[i, S_UPN] = s_old[i, S_UPN] + du[1]
                plastic = True
                switched[i] = 1
        elif du[0] == 0.0 and du[1] == 0.0:
            # start of a step at a plastic point: committed traction and tangent
            d[:, :] = d_old[i]
            s_new[i, S_DGAMMA] = 0.0
            plastic = True
        else:
            x[0] = s_prev[i, S_TT]
            x[1] = s_prev[i, S_TN]
            x[2] = s_prev[i, S_EPSN]
            x[3] = s_prev[i, S_EPSS]
            x[4] = s_prev[i, S_DGAMMA]
            st = rp_update(du, s_old[i], p, x, s_new[i], d)
            if st == -2:
                switched[i] = 1  # unloading: back to the constrained state
            elif st < 0:
                status[i] = -1
                continue
            else:
                plastic = True
        fi = fe[i]
        ki = ke[i]
        ki[:, :] = 0.0
        if plastic:
            s_new[i, S_MODE] = 1.0
            tg = np.empty(2)
            dg = np.empty((2, 2))
            _rotate_back(r, s_new[i, S_TT : S_TN + 1], d, tg, dg)
            _pair_blocks(w, tg, dg, fi, ki)
            for a in range(2):
                fi[4 + a] = w * (lam[i, a] - tg[a])
                ki[4 + a, 4 + a] = w
                for b in range(2):
                    ki[4 + a, b] = w * dg[a, b]
                    ki[4 + a, 2 + b] = -w * dg[a, b]
        else:
            s_new[i, :] = s_old[i, :]
            s_new[i, S_MODE] = 0.0
            s_new[i, S_DGAMMA] = 0.0
            tg = np.empty(2)
            for a in range(2):
                tg[a] = lam[i, a] + aug * h[a]
            s_new[i, S_TT] = r[0, 0] * tg[0] + r[0, 1] * tg[1]
            s_new[i, S_TN] = r[1, 0] * tg[0] + r[1, 1] * tg[1]
            for a in range(2):
                fi[a] = -w * tg[a]
                fi[2 + a] = w * tg[a]
                fi[4 + a] = w * aug * h[a]
                ki[a, a] = w * aug
                ki[a, 2 + a] = -w * aug
                ki[2 + a, a] = -w * aug
                ki[2 + a, 2 + a] = w * aug
                ki[a, 4 + a] = -w
                ki[2 + a, 4 + a] = w
                ki[4 + a, a] = -w * aug
                ki[4 + a, 2 + a] = w * aug
            d[:, :] = 0.0
