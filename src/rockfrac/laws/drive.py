"""Material-point driver of the cohesive law (EP form, Sect. 6.1) along a prescribed jump path.

The path gives total local jumps ``[t, n]`` [m] at successive points, starting implicitly from a
zero jump and the virgin state. A step whose local solve fails is sub-stepped by recursive halving.
"""

from __future__ import annotations

import numpy as np

from rockfrac.compiled import inner, kernel
from rockfrac.laws.cohesive import ep_update
from rockfrac.laws.cohesive_params import (
    N_STATE,
    S_EPSN,
    S_EPSS,
    S_TN,
    S_TT,
    S_UPN,
    S_UPT,
    CohesiveLaw,
)
from rockfrac.laws.cohesive_surface import strengths_points

MAX_HALVINGS = 20


@inner
def _advance(u_from, u_to, s, p, max_halvings):
    """Move the state s (N_STATE,) from total jump u_from to u_to [m] in place, halving on failure.

    Sub-increments are dyadic fractions of the step; returns True on success.
    """
    s_new = np.empty(N_STATE)
    d = np.empty((2, 2))
    du = np.empty(2)
    done = 0.0
    frac = 1.0
    u_cur = u_from.copy()
    min_frac = 0.5**max_halvings
    while done < 1.0:
        f = min(frac, 1.0 - done)
        target = u_from + (done + f) * (u_to - u_from)
        du[:] = target - u_cur
        if ep_update(du, s, p, s_new, d) < 0:
            frac *= 0.5
            if frac < min_frac:
                return False
            continue
        s[:] = s_new
        u_cur[:] = target
        done += f
    return True


@kernel
def _drive_kernel(jumps, p, states, max_halvings):
    """Fill states (n, N_STATE) along the path jumps (n, 2); returns the 0-based failing row or -1."""
    s = np.zeros(N_STATE)
    u_prev = np.zeros(2)
    for i in range(jumps.shape[0]):
        if not _advance(u_prev, jumps[i].copy(), s, p, max_halvings):
            return i
        states[i, :] = s
        u_prev[:] = jumps[i]
    return -1


def drive_path(law: CohesiveLaw, jumps: np.ndarray) -> dict[str, np.ndarray]:
    """Drive one EP material point along total local jumps (n, 2) [t, n] in m from zero.

    Returns 1-D arrays per path point: step (1..n), jump_t, jump_n, T_t, T_n [Pa], jump_p_t,
    jump_p_n [m], eps_n_p, eps_s_p, chi, c [Pa], tan_phi, tan_psi.
    """
    if law.rigid:
        raise ValueError("drive_path needs the EP form of the law: give finite kn and kt "
                         "(the rigid-plastic form has no elastic jump to drive)")
    jumps = np.ascontiguousarray(jumps, dtype=np.float64)
    if jumps.ndim != 2 or jumps.shape[1] != 2:
        raise ValueError(f"jumps must have shape (n, 2) [jump_t, jump_n], got {jumps.shape}")
    p = law.as_array()
    states = np.zeros((jumps.shape[0], N_STATE))
    bad = _drive_kernel(jumps, p, states, MAX_HALVINGS)
    if bad >= 0:
        raise RuntimeError(f"cohesive law: local return map failed at path step {bad + 1} "
                           f"(jump {jumps[bad].tolist()} m) even after {MAX_HALVINGS} halvings")
    q = strengths_points(states[:, S_EPSN].copy(), states[:, S_EPSS].copy(), p)
    return {
        "step": np.arange(1, jumps.shape[0] + 1),
        "jump_t": jumps[:, 0].copy(),
        "jump_n": jumps[:, 1].copy(),
        "T_t": states[:, S_TT].copy(),
        "T_n": states[:, S_TN].copy(),
        "jump_p_t": states[:, S_UPT].copy(),
        "jump_p_n": states[:, S_UPN].copy(),
        "eps_n_p": states[:, S_EPSN].copy(),
        "eps_s_p": states[:, S_EPSS].copy(),
        "chi": q[:, 0],
        "c": q[:, 1],
        "tan_phi": q[:, 2],
        "tan_psi": q[:, 3],
    }
