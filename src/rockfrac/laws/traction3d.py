"""The cohesive traction laws in 3D, isotropic in the interface plane: local frame (t1, t2, n), tension
positive, tractions in Pa, jumps in m.

The laws' flow potentials depend on T_t = (T_t1, T_t2) only through |T_t| and their tangential return
is radial, so the 3D return is the law's 2D return (its ``trial_kernel``) on the plane of
e = T_t^tr / |T_t^tr| and n, from the trial (|T_t^tr|, T_n^tr) with T_old2 = (e . T_old_t, T_old_n):
T_t = (2D T_t) e, jump_p_t += (2D increment) e, and with A = dT2/dT_tr2 of the 2D law

    dT_t/dT_t^tr = A_tt e e^T + (|T_t| / |T_t^tr|) (I - e e^T), dT_t/dT_n^tr = A_tn e,
    dT_n/dT_t^tr = A_nt e^T, D3 = (dT/dT^tr) K   (e = t1, ratio -> A_tt at |T_t^tr| = 0).

Exact where the 2D result is a function of the trial alone; the Mohr-Coulomb 'trapezoidal' work rule
is not (its start-of-flow traction depends on the elastic path, not planar in 3D) and is refused.
The 2D kernel enters the compiled loops as a cfunc (:func:`trial_function`), typed by its signature
and not its identity, so Numba's on-disk cache serves the loops of every law.
"""

from __future__ import annotations

import math
import types
from typing import Any

import numba as nb
import numpy as np

from rockfrac.compiled import inner, kernel
from rockfrac.fem.interface import CHUNK, local_jump_3d, multiplier_rows_3d, pair_blocks_3d
from rockfrac.laws.mohr_coulomb_surface import MohrCoulombSurface
from rockfrac.laws.traction_law import MODE_PLASTIC, TractionLaw, keep_committed
from rockfrac.threads import parallel_kernel

S_TT1, S_TT2, S_TN, S_UPT1, S_UPT2, S_UPN = 0, 1, 2, 3, 4, 5  # the common 3D state slots
COMMON_STATE_3D = ("T_t1", "T_t2", "T_n", "jump_p_t1", "jump_p_t2", "jump_p_n")
SHIFT = 2  # a law's own slot k of its 2D state is slot k + SHIFT of the 3D one
MAX_HALVINGS = 20  # the driver's sub-steps of a failing step, as rockfrac.laws.drive

_F8 = nb.types.float64
TRIAL_SIGNATURE = nb.types.int64(_F8, _F8, _F8, _F8, _F8[::1], _F8[::1], _F8[::1], _F8[:, ::1])
_FIRST_CLASS: dict[Any, Any] = {}  # trial_kernel -> its cfunc


def state_names_3d(law_cls: type[TractionLaw]) -> tuple[str, ...]:
    """The 3D state vector's slot names: COMMON_STATE_3D, then the law's own slots."""
    return COMMON_STATE_3D + tuple(law_cls.state_names[4:])


def mode_slot_3d(law_cls: type[TractionLaw]) -> int:
    """Where the 3D state keeps the law's mode (0 elastic/constrained, 1 plastic)."""
    return law_cls.mode_slot + SHIFT


def dgamma_slot_3d(law_cls: type[TractionLaw]) -> int:
    """Where the 3D state keeps the last update's plastic multiplier increment."""
    return law_cls.dgamma_slot + SHIFT


def trial_function(law_cls: type[TractionLaw]) -> Any:
    """The law's ``trial_kernel`` as a first-class function of TRIAL_SIGNATURE (a cfunc, cached on
    disk under a name of its own: a renamed copy, so it never shares the njit version's cache index)."""
    kernel = law_cls.trial_kernel
    if kernel not in _FIRST_CLASS:
        f = kernel.py_func
        copy = types.FunctionType(f.__code__, f.__globals__, f.__name__ + "__cfunc", f.__defaults__, f.__closure__)
        copy.__qualname__ = f.__qualname__ + "__cfunc"
        copy.__module__ = f.__module__
        _FIRST_CLASS[kernel] = nb.cfunc(TRIAL_SIGNATURE, cache=True)(copy)
    return _FIRST_CLASS[kernel]


def check_3d(law: TractionLaw) -> None:
    """ValueError if the law's 2D return is not a function of the trial alone (then it has no 3D form)."""
    if isinstance(law, MohrCoulombSurface) and law.law.work_rule != "backward_euler":
        raise ValueError(f"work_rule = {law.law.work_rule!r} is 2D only: its start-of-flow traction depends on "
                         "the elastic path, which is not planar in 3D; use 'backward_euler'")


# --------------------------------------------------------------------------------------------
# one point
# --------------------------------------------------------------------------------------------


@inner
def update_3d(ret, tr_t1, tr_t2, tr_n, to_t1, to_t2, to_n, ct, cn, s_old, p, s_new, D, s2o, s2n, d2):
    """3D return via the 2D ``ret`` from the local trial tr_* = to_* + K du [Pa], K = diag(1/ct, 1/ct, 1/cn);
    D (3, 3) = dT/d(du) [Pa/m]; scratch s2o, s2n (n_state3 - 2,), d2 (2, 2); returns ret's status."""
    rt = math.sqrt(tr_t1 * tr_t1 + tr_t2 * tr_t2)
    e1, e2 = 1.0, 0.0
    if rt > 0.0:
        e1, e2 = tr_t1 / rt, tr_t2 / rt
    n2 = s2o.shape[0]
    s2o[0] = e1 * to_t1 + e2 * to_t2  # T_old2: consistent, T_old2 + K du2 is the 2D trial
    s2o[1] = to_n
    s2o[2] = 0.0  # the 2D plastic jump slots return the increments
    s2o[3] = 0.0
    for k in range(4, n2):
        s2o[k] = s_old[k + SHIFT]
    st = ret(rt, tr_n, ct, cn, s2o, p, s2n, d2)
    if st < 0:
        return st
    tt = s2n[0]
    if tt == rt:  # the trial's tangential traction (elastic): exactly
        s_new[S_TT1], s_new[S_TT2] = tr_t1, tr_t2
    else:
        s_new[S_TT1], s_new[S_TT2] = tt * e1, tt * e2
    s_new[S_TN] = s2n[1]
    s_new[S_UPT1] = s_old[S_UPT1] + s2n[2] * e1
    s_new[S_UPT2] = s_old[S_UPT2] + s2n[2] * e2
    s_new[S_UPN] = s_old[S_UPN] + s2n[3]
    for k in range(4, n2):
        s_new[k + SHIFT] = s2n[k]
    ratio = d2[0, 0]  # (|T_t| / |T_t^tr|) kt -> A_tt kt as rt -> 0: taken below 1e-8 |T_n^tr|, where the two
    if rt > 1.0e-8 * abs(tr_n):  # agree to O(1e-16) and tt / rt would carry the solver's noise
        ratio = tt / rt / ct
    D[0, 0] = d2[0, 0] * e1 * e1 + ratio * (1.0 - e1 * e1)  # the 2D tangent's bits when e = +-t1
    D[1, 1] = d2[0, 0] * e2 * e2 + ratio * (1.0 - e2 * e2)
    D[0, 1] = (d2[0, 0] - ratio) * e1 * e2
    D[1, 0] = D[0, 1]
    D[0, 2], D[1, 2] = d2[0, 1] * e1, d2[0, 1] * e2
    D[2, 0], D[2, 1] = d2[1, 0] * e1, d2[1, 0] * e2
    D[2, 2] = d2[1, 1]
    return st


@kernel
def ep_update_3d(ret, du, s_old, p, ct, cn, s_new, D):
    """One EP update of one point by the local jump increment du (3,) [m], K = diag(1/ct, 1/ct, 1/cn);
    D (3, 3) = dT/d(du) [Pa/m]. Returns the law's status (0 elastic, 1 plastic, < 0 failure)."""
    n2 = s_old.shape[0] - SHIFT
    return update_3d(ret, s_old[S_TT1] + du[0] / ct, s_old[S_TT2] + du[1] / ct, s_old[S_TN] + du[2] / cn, s_old[S_TT1],
                     s_old[S_TT2], s_old[S_TN], ct, cn, s_old, p, s_new, D, np.empty(n2), np.empty(n2), np.empty((2, 2)))


# --------------------------------------------------------------------------------------------
# the EP and RP forms at n points
# --------------------------------------------------------------------------------------------


@parallel_kernel(cost=1.4e-6)  # s per item, one thread: the 2D Mohr-Coulomb estimate
def ep_points_3d(frame, weight, djump, s_old, d_old, p, s_new, d_new, fe, ke, status, ret, ct, cn, mode_slot,
                 dgamma_slot):
    """EP form at n points: frame (n, 3, 3) rows (t1, t2, n), weight (n,) [m^2], djump (n, 3) global
    jump increment [m], states (n, n_state3), tangents (n, 3, 3) [Pa/m], fe (n, 6), ke (n, 6, 6),
    status (n,); ret = trial_function(law), ct, cn = 1/kt, 1/kn [m/Pa], the law's 3D slots."""
    n = frame.shape[0]
    n2 = s_old.shape[1] - SHIFT
    for c in nb.prange((n + CHUNK - 1) // CHUNK):
        s2o, s2n, d2 = np.empty(n2), np.empty(n2), np.empty((2, 2))  # scratch per chunk
        for i in range(c * CHUNK, min(n, (c + 1) * CHUNK)):
            r = frame[i]
            so = s_old[i]
            du0, du1, du2 = local_jump_3d(r, djump[i])
            if du0 == 0.0 and du1 == 0.0 and du2 == 0.0 and so[mode_slot] == MODE_PLASTIC:
                keep_committed(so, d_old[i], s_new[i], d_new[i], dgamma_slot)
                status[i] = 1
            else:
                status[i] = update_3d(ret, so[S_TT1] + du0 / ct, so[S_TT2] + du1 / ct, so[S_TN] + du2 / cn,
                                      so[S_TT1], so[S_TT2], so[S_TN], ct, cn, so, p, s_new[i], d_new[i], s2o, s2n,
                                      d2)
            pair_blocks_3d(r, weight[i], s_new[i], d_new[i], fe[i], ke[i])


@parallel_kernel(cost=1.4e-6)  # s per item, one thread: the 2D Mohr-Coulomb estimate
def rp_points_3d(frame, weight, djump, lam, aug, eps, pinned, s_old, d_old, mode_prev, p, s_new, d_new, fe, ke,
                 status, switched, ret, mode_slot, dgamma_slot):
    """RP form at n points (rockfrac.laws.mohr_coulomb_surface.rp_points in 3D): the return at the
    augmented trial lambda + r h, dofs (n, 9) = (minus xyz, plus xyz, lambda xyz); lam (n, 3) global
    multipliers [Pa], aug = r [Pa/m], djump = h (n, 3) [m]; ret, slots as :func:`ep_points_3d`."""
    n = frame.shape[0]
    n2 = s_old.shape[1] - SHIFT
    comp = 1.0 / aug
    for c in nb.prange((n + CHUNK - 1) // CHUNK):
        s2o, s2n, d2 = np.empty(n2), np.empty(n2), np.empty((2, 2))
        for i in range(c * CHUNK, min(n, (c + 1) * CHUNK)):
            r = frame[i]
            so, sn, dn = s_old[i], s_new[i], d_new[i]
            h0, h1, h2 = local_jump_3d(r, djump[i])
            l0, l1, l2 = local_jump_3d(r, lam[i])
            if h0 == 0.0 and h1 == 0.0 and h2 == 0.0 and so[mode_slot] == MODE_PLASTIC and not pinned[i]:
                keep_committed(so, d_old[i], sn, dn, dgamma_slot)
                status[i] = 1
            elif pinned[i]:  # the constrained branch of eq. (33): T = lambda + r h, D = r I
                for k in range(so.shape[0]):
                    sn[k] = so[k]
                sn[S_TT1], sn[S_TT2], sn[S_TN] = l0 + aug * h0, l1 + aug * h1, l2 + aug * h2
                sn[dgamma_slot] = 0.0
                sn[mode_slot] = 0.0
                dn[:, :] = 0.0
                for k in range(3):
                    dn[k, k] = aug
                status[i] = 0
            else:
                status[i] = update_3d(ret, l0 + aug * h0, l1 + aug * h1, l2 + aug * h2, l0, l1, l2, comp, comp, so,
                                      p, sn, dn, s2o, s2n, d2)
            switched[i] = 1 if sn[mode_slot] != mode_prev[i] else 0
            pair_blocks_3d(r, weight[i], sn, dn, fe[i], ke[i])
            multiplier_rows_3d(r, weight[i], sn, lam[i], aug, eps[i], eps[i] > 0.0 and sn[mode_slot] != MODE_PLASTIC,
                               fe[i], ke[i])


def ep_form_3d(law: TractionLaw, frame, weight, djump, s_old, d_old, s_new, d_new, fe, ke, status) -> None:
    """:func:`ep_points_3d` with the law's kernel, penalties and slots (ValueError: no 3D or no EP form)."""
    check_3d(law)
    if law.rigid:
        raise ValueError("the EP form needs finite kn and kt")
    assert law.kt is not None and law.kn is not None
    ep_points_3d(frame, weight, djump, s_old, d_old, law.p, s_new, d_new, fe, ke, status, trial_function(type(law)),
                 1.0 / law.kt, 1.0 / law.kn, mode_slot_3d(type(law)), dgamma_slot_3d(type(law)))


def rp_form_3d(law: TractionLaw, frame, weight, djump, lam, aug, eps, pinned, s_old, d_old, mode_prev, s_new, d_new,
               fe, ke, status, switched) -> None:
    """:func:`rp_points_3d` with the law's kernel and slots (ValueError if the law has no 3D form)."""
    check_3d(law)
    rp_points_3d(frame, weight, djump, lam, aug, eps, pinned, s_old, d_old, mode_prev, law.p, s_new, d_new, fe, ke,
                 status, switched, trial_function(type(law)), mode_slot_3d(type(law)), dgamma_slot_3d(type(law)))


# --------------------------------------------------------------------------------------------
# the material-point driver
# --------------------------------------------------------------------------------------------


@kernel
def _drive_kernel(ret, jumps, ct, cn, p, states, max_halvings):
    """States (n, n_state3) along total local jumps (n, 3) [m] from zero, a failing step halved (as
    rockfrac.laws.drive._advance); returns the 0-based failing row or -1."""
    n3 = states.shape[1]
    s, s_new, d = np.zeros(n3), np.empty(n3), np.empty((3, 3))
    s2o, s2n, d2 = np.empty(n3 - SHIFT), np.empty(n3 - SHIFT), np.empty((2, 2))
    u_from, u_cur, target = np.zeros(3), np.zeros(3), np.empty(3)
    min_frac = 0.5**max_halvings
    for i in range(jumps.shape[0]):
        done, frac = 0.0, 1.0
        u_cur[:] = u_from
        while done < 1.0:
            f = min(frac, 1.0 - done)
            for k in range(3):
                target[k] = u_from[k] + (done + f) * (jumps[i, k] - u_from[k])
            du0, du1, du2 = target[0] - u_cur[0], target[1] - u_cur[1], target[2] - u_cur[2]
            st = update_3d(ret, s[S_TT1] + du0 / ct, s[S_TT2] + du1 / ct, s[S_TN] + du2 / cn, s[S_TT1], s[S_TT2],
                           s[S_TN], ct, cn, s, p, s_new, d, s2o, s2n, d2)
            if st < 0:
                frac *= 0.5
                if frac < min_frac:
                    return i
                continue
            s[:] = s_new
            u_cur[:] = target
            done += f
        states[i, :] = s
        u_from[:] = jumps[i]
    return -1


def drive_3d(law: TractionLaw, jumps: np.ndarray) -> dict[str, np.ndarray]:
    """The EP form along total local jumps (n, 3) [t1, t2, n] in m from zero: step, jump_t1, jump_t2,
    jump_n, the 3D state's common slots [Pa, m] and the law's records, one row per path point."""
    check_3d(law)
    if law.rigid:
        raise ValueError("drive_3d needs the EP form of the law: give finite kn and kt")
    assert law.kt is not None and law.kn is not None
    jumps = np.ascontiguousarray(jumps, dtype=np.float64)
    if jumps.ndim != 2 or jumps.shape[1] != 3:
        raise ValueError(f"jumps must have shape (n, 3) [jump_t1, jump_t2, jump_n], got {jumps.shape}")
    names = state_names_3d(type(law))
    states = np.zeros((jumps.shape[0], len(names)))
    bad = _drive_kernel(trial_function(type(law)), jumps, 1.0 / law.kt, 1.0 / law.kn, law.p, states, MAX_HALVINGS)
    if bad >= 0:
        raise RuntimeError(f"{law.name} law (3D): the local return failed at path step {bad + 1} (jump "
                           f"{jumps[bad].tolist()} m) even after {MAX_HALVINGS} halvings")
    out = {"step": np.arange(1, jumps.shape[0] + 1), "jump_t1": jumps[:, 0].copy(), "jump_t2": jumps[:, 1].copy(),
           "jump_n": jumps[:, 2].copy()}
    out.update({name: states[:, k].copy() for k, name in enumerate(COMMON_STATE_3D)})
    out.update(law.records(planar_states(states)))
    return out


def planar_states(states: np.ndarray) -> np.ndarray:
    """2D-layout states (n, n_state3 - 2) of 3D ones: |T_t|, T_n, |jump_p_t|, jump_p_n, the law's slots."""
    out = np.empty((states.shape[0], states.shape[1] - SHIFT))
    out[:, 0] = np.hypot(states[:, S_TT1], states[:, S_TT2])
    out[:, 1] = states[:, S_TN]
    out[:, 2] = np.hypot(states[:, S_UPT1], states[:, S_UPT2])
    out[:, 3] = states[:, S_UPN]
    out[:, 4:] = states[:, 4 + SHIFT:]
    return out
