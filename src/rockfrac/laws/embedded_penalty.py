"""The embedded crack's Mohr-Coulomb law (paper Sect. 4.1) in elasto-plastic penalty form, for cracks
whose jump is a nodal field (rockfrac.elements.ede_nodal). Local frame (t, n), 2D.

The rigid-plastic law of Sect. 4.1 with an elastic jump of penalty stiffness K = diag(kt, kn) in
front of it, starting from the traction T0 the crack had when it was cut (its stress then):

    T = T0 + K ([[u]] - J_p),   F = s T_t + tan(phi) min(T_n, 0) - c,   s = sign(T_t),
    dJ_p = d(zeta) m,   m = (s cos(psi), sin(psi)),   gamma = gamma_n + cos(psi) d(zeta),

with c, phi, psi of gamma (:func:`rockfrac.laws.mohr_coulomb_softening.strengths`, backward Euler
in gamma by :func:`gamma_of`). With c_p from eq. (28) on the stress at the cut, F = 0 there: the
crack is at its peak when it appears and the stress is continuous in time. As K grows the elastic
jump K^-1 (T - T0) vanishes and the law is the rigid-plastic one of the elemental EDE.

Backward Euler return: one scalar root in d(zeta) >= 0, bracketed (F > 0 at 0, F < 0 once the
shear traction has been returned past zero), found by a safeguarded Newton; consistent tangent

    D = K - (K m~)(K a)^T / (a . K m~ - b gamma'),   a = dF/dT,  b = dF/dgamma,
    m~ = d(d(zeta) m)/d(d(zeta)),   gamma' = d gamma / d(d(zeta)).

State slots per crack point: the CP_* constants.
"""

from __future__ import annotations

import math

import numpy as np

from rockfrac.compiled import inner, kernel
from rockfrac.laws.mohr_coulomb_softening import gamma_of, strengths

CP_T0 = 0  # traction when the crack was cut (t, n) [Pa], slots 0..1
CP_JP = 2  # plastic jump (t, n) [m], slots 2..3
CP_GAMMA = 4  # gamma [m]
CP_ZETA = 5  # accumulated slip zeta [m]
CP_CP = 6  # peak cohesion c_p [Pa] (eq. 28)
CP_T = 7  # traction (t, n) [Pa], slots 7..8
CP_J = 9  # jump (t, n) [m], slots 9..10
CP_MODE = 11  # 0 elastic, 1 sliding, 2 opening in tension, 3 both (the corner) in the last update
CP_DZ = 12  # d(zeta) of the last update [m]
CP_SIGN = 13  # s of the last plastic update
N_CP = 14

ST_OK = 0
ST_NO_RETURN = -1  # the scalar return did not converge


@inner
def _crack_state(dz, dl, s, tt_tr, tn_tr, kt, kn, gamma_n, c_p, law, out, dt, dr, rt):
    """The state at the slip dz >= 0 and opening dl >= 0 of the step: out = (T_t, T_n, gamma, R1, R2,
    psi) with R1 the shear surface and R2 the tension cut-off; dt = d(T_t, T_n)/d(dz, dl),
    dr = d(R1, R2)/d(dz, dl) (at fixed jump), rt = d(R1, R2)/d(T_t, T_n)."""
    gamma, dgam = gamma_of(dz, gamma_n + dl, law)  # gamma = gamma_n + dl + cos(psi) dz, backward Euler
    c, tphi, psi, dc, dtphi, dpsi = strengths(gamma, c_p, law)
    cp, sp = math.cos(psi), math.sin(psi)
    g_dz, g_dl = dgam, dgam / cp  # d gamma / d dz, d gamma / d dl
    t_t = tt_tr - kt * s * cp * dz
    t_n = tn_tr - kn * (sp * dz + dl)
    comp = 1.0 if t_n < 0.0 else 0.0
    dt[0, 0] = -kt * s * (cp - sp * dz * dpsi * g_dz)
    dt[0, 1] = kt * s * sp * dz * dpsi * g_dl
    dt[1, 0] = -kn * (sp + cp * dz * dpsi * g_dz)
    dt[1, 1] = -kn * (1.0 + cp * dz * dpsi * g_dl)
    rt[0, 0], rt[0, 1] = s, tphi * comp
    rt[1, 0], rt[1, 1] = 0.0, 1.0
    b1 = dtphi * min(t_n, 0.0) - dc
    for j in range(2):
        g_j = g_dz if j == 0 else g_dl
        dr[0, j] = rt[0, 0] * dt[0, j] + rt[0, 1] * dt[1, j] + b1 * g_j
        dr[1, j] = dt[1, j] - dc * g_j
    out[0], out[1], out[2] = t_t, t_n, gamma
    out[3] = s * t_t + tphi * min(t_n, 0.0) - c
    out[4] = t_n - c
    out[5] = psi


@inner
def _one_surface(k, s, tt_tr, tn_tr, kt, kn, gamma_n, c_p, law, scale, out, dt, dr, rt):
    """The return onto surface k alone (0: shear, 1: tension cut-off) by a safeguarded Newton inside a
    bracket (R_k > 0 at 0, < 0 at its upper end); returns its multiplier, or -1 if it did not converge."""
    lo, hi = 0.0, (abs(tt_tr) / kt if k == 0 else max(tn_tr, 0.0) / kn) + 1e-300
    for _ in range(60):
        dz, dl = (hi, 0.0) if k == 0 else (0.0, hi)
        _crack_state(dz, dl, s, tt_tr, tn_tr, kt, kn, gamma_n, c_p, law, out, dt, dr, rt)
        if out[3 + k] <= 0.0:
            break
        lo, hi = hi, 2.0 * hi
    x = lo
    for _ in range(200):
        dz, dl = (x, 0.0) if k == 0 else (0.0, x)
        _crack_state(dz, dl, s, tt_tr, tn_tr, kt, kn, gamma_n, c_p, law, out, dt, dr, rt)
        f, df = out[3 + k], dr[k, k]
        if abs(f) <= 1e-12 * scale:
            return x
        if f > 0.0:
            lo = max(lo, x)
        else:
            hi = min(hi, x)
        step = x - f / df if df < 0.0 else -1.0
        x = step if lo < step < hi else 0.5 * (lo + hi)  # Newton inside the bracket, else bisection
        if hi - lo <= 1e-15 * max(hi, 1e-300):
            dz, dl = (x, 0.0) if k == 0 else (0.0, x)
            _crack_state(dz, dl, s, tt_tr, tn_tr, kt, kn, gamma_n, c_p, law, out, dt, dr, rt)
            return x if abs(out[3 + k]) <= 1e-9 * scale else -1.0
    return -1.0


@inner
def _tangent(active, kt, kn, dt, dr, rt, d):
    """d (2, 2) = K - dT/dx (dR/dx)^-1 dR/dT K over the active surfaces (0 shear, 1 cut-off, 2 both;
    -1: none, d = K), from :func:`_crack_state`'s derivatives."""
    d[0, 0], d[0, 1], d[1, 0], d[1, 1] = kt, 0.0, 0.0, kn
    if active == 2:
        det = dr[0, 0] * dr[1, 1] - dr[0, 1] * dr[1, 0]
        inv = np.empty((2, 2))
        inv[0, 0], inv[0, 1], inv[1, 0], inv[1, 1] = dr[1, 1] / det, -dr[0, 1] / det, -dr[1, 0] / det, dr[0, 0] / det
        rk = np.empty((2, 2))
        for i in range(2):
            rk[i, 0], rk[i, 1] = rt[i, 0] * kt, rt[i, 1] * kn
        for i in range(2):
            for j in range(2):
                acc = 0.0
                for a in range(2):
                    for b in range(2):
                        acc += dt[i, a] * inv[a, b] * rk[b, j]
                d[i, j] -= acc
    elif active >= 0:
        k = active
        for i in range(2):
            d[i, 0] -= dt[i, k] * rt[k, 0] * kt / dr[k, k]
            d[i, 1] -= dt[i, k] * rt[k, 1] * kn / dr[k, k]


@inner
def return_trial(tt_tr, tn_tr, s, gamma_n, c_p, old_mode, law, kt, kn, res, d):
    """The return of a trial traction (tt_tr, tn_tr) [Pa] from a point at gamma_n with peak cohesion
    c_p whose last update was old_mode (module doc): res = (T_t, T_n, gamma, psi, dz, dl, mode) and
    the tangent d (2, 2) = dT/d[[u]] in (t, n) [Pa/m]. Returns ST_OK or ST_NO_RETURN.

    Two surfaces: the shear surface R1 = s T_t + tan(phi) min(T_n, 0) - c (slip dz along m) and the
    tension cut-off R2 = T_n - c (opening dl along n: the crack holds no more tension than its
    cohesion, none once that is gone); gamma = gamma_n + dl + cos(psi) dz. The active set is the
    shear surface, else the cut-off, else both (the corner), whichever return satisfies the other."""
    out = np.empty(6)
    dt = np.empty((2, 2))
    dr = np.empty((2, 2))
    rt = np.empty((2, 2))
    _crack_state(0.0, 0.0, s, tt_tr, tn_tr, kt, kn, gamma_n, c_p, law, out, dt, dr, rt)
    scale = max(c_p, abs(tt_tr), abs(tn_tr), 1.0)
    tol = 1e-12 * scale
    res[4], res[5] = 0.0, 0.0
    if out[3] <= tol and out[4] <= tol:
        res[0], res[1], res[2], res[3], res[6] = tt_tr, tn_tr, gamma_n, out[5], 0.0
        d[0, 0], d[0, 1], d[1, 0], d[1, 1] = kt, 0.0, 0.0, kn
        # on the surface of the last update's plastic flow (a step's first iterate: the committed
        # jump): its tangent, not the elastic one (the point goes on flowing unless the step unloads
        # it; the traction is the same either way)
        on1, on2 = abs(out[3]) <= 1e-9 * scale, abs(out[4]) <= 1e-9 * scale
        active = -1
        if old_mode == 3.0 and on1 and on2:
            active = 2
        elif (old_mode == 1.0 or old_mode == 3.0) and on1:
            active = 0
        elif (old_mode == 2.0 or old_mode == 3.0) and on2:
            active = 1
        if active >= 0:
            _tangent(active, kt, kn, dt, dr, rt, d)
        return ST_OK
    status = ST_NO_RETURN
    active = -1  # 0 shear, 1 tension, 2 both
    dz, dl = 0.0, 0.0
    f1_trial, f2_trial = out[3], out[4]
    if f1_trial > tol:
        x = _one_surface(0, s, tt_tr, tn_tr, kt, kn, gamma_n, c_p, law, scale, out, dt, dr, rt)
        if x >= 0.0 and out[4] <= tol:
            active, dz, status = 0, x, ST_OK
        elif x >= 0.0:
            dz = x
    if active < 0 and f2_trial > tol:
        x = _one_surface(1, s, tt_tr, tn_tr, kt, kn, gamma_n, c_p, law, scale, out, dt, dr, rt)
        if x >= 0.0 and out[3] <= tol:
            active, dl, dz, status = 1, x, 0.0, ST_OK
        elif x >= 0.0:
            dl = x
    if active < 0:  # the corner: both surfaces, Newton on (dz, dl) from the single-surface returns
        dz, dl = max(dz, 0.0), max(dl, 0.0)
        for _ in range(100):
            _crack_state(dz, dl, s, tt_tr, tn_tr, kt, kn, gamma_n, c_p, law, out, dt, dr, rt)
            r1, r2 = out[3], out[4]
            if abs(r1) <= tol and abs(r2) <= tol:
                active, status = 2, ST_OK
                break
            det = dr[0, 0] * dr[1, 1] - dr[0, 1] * dr[1, 0]
            if det == 0.0:
                break
            ddz = -(dr[1, 1] * r1 - dr[0, 1] * r2) / det
            ddl = -(-dr[1, 0] * r1 + dr[0, 0] * r2) / det
            dz, dl = max(dz + ddz, 0.0), max(dl + ddl, 0.0)
        _crack_state(dz, dl, s, tt_tr, tn_tr, kt, kn, gamma_n, c_p, law, out, dt, dr, rt)
    _tangent(active, kt, kn, dt, dr, rt, d)
    res[0], res[1], res[2], res[3], res[4], res[5] = out[0], out[1], out[2], out[5], dz, dl
    res[6] = (1.0, 2.0, 3.0)[active] if active >= 0 else 1.0
    return status


@inner
def crack_return(j_t, j_n, st_old, law, kt, kn, st_new, tr, d):
    """One update of a crack point at the jump (j_t, j_n) [m] (module doc, :func:`return_trial`):
    st_new, the traction tr (2,) [Pa] and the tangent d (2, 2) [Pa/m] in (t, n). Returns ST_OK or
    ST_NO_RETURN."""
    for k in range(st_old.shape[0]):
        st_new[k] = st_old[k]
    tt_tr = st_old[CP_T0] + kt * (j_t - st_old[CP_JP])
    tn_tr = st_old[CP_T0 + 1] + kn * (j_n - st_old[CP_JP + 1])
    s = 1.0 if tt_tr >= 0.0 else -1.0
    res = np.empty(7)
    status = return_trial(tt_tr, tn_tr, s, st_old[CP_GAMMA], st_old[CP_CP], st_old[CP_MODE], law, kt, kn, res, d)
    t_t, t_n, gamma, psi, dz, dl, mode = res[0], res[1], res[2], res[3], res[4], res[5], res[6]
    tr[0], tr[1] = t_t, t_n
    st_new[CP_J], st_new[CP_J + 1] = j_t, j_n
    st_new[CP_T], st_new[CP_T + 1] = t_t, t_n
    st_new[CP_DZ] = dz
    st_new[CP_MODE] = mode
    if mode == 0.0:
        return status
    st_new[CP_JP] = st_old[CP_JP] + dz * s * math.cos(psi)
    st_new[CP_JP + 1] = st_old[CP_JP + 1] + dz * math.sin(psi) + dl
    st_new[CP_GAMMA] = gamma
    st_new[CP_ZETA] = st_old[CP_ZETA] + dz
    st_new[CP_SIGN] = s
    return status


@kernel
def crack_point_update(j_t, j_n, st_old, law, kt, kn):
    """:func:`crack_return` from Python (tests, drivers): (status, new state, traction (2,), tangent (2, 2))."""
    st_new = np.empty(st_old.shape[0])
    tr = np.empty(2)
    d = np.empty((2, 2))
    status = crack_return(j_t, j_n, st_old, law, kt, kn, st_new, tr, d)
    return status, st_new, tr, d


def initial_state(traction_t: float, traction_n: float, c_p: float) -> np.ndarray:
    """A crack point's state when its cell is cut: the stress's traction (t, n) [Pa] on the new
    surface, no jump yet, and its peak cohesion c_p [Pa]."""
    st = np.zeros(N_CP)
    st[CP_T0], st[CP_T0 + 1] = traction_t, traction_n
    st[CP_T], st[CP_T + 1] = traction_t, traction_n
    st[CP_CP] = c_p
    st[CP_SIGN] = 1.0 if traction_t >= 0.0 else -1.0
    return st


# -- the law in 3D: isotropic in the crack's plane -------------------------------------------------

C3_T0 = 0  # traction when the crack was cut (t1, t2, n) [Pa], slots 0..2
C3_JP = 3  # plastic jump (t1, t2, n) [m], slots 3..5
C3_GAMMA = 6  # gamma [m]
C3_ZETA = 7  # accumulated slip zeta [m]
C3_CP = 8  # peak cohesion c_p [Pa]
C3_T = 9  # traction (t1, t2, n) [Pa], slots 9..11
C3_J = 12  # jump (t1, t2, n) [m], slots 12..14
C3_MODE = 15  # as CP_MODE
C3_DZ = 16  # d(zeta) of the last update [m]
N_C3 = 17


@inner
def crack_return_3d(j, st_old, law, kt, kn, st_new, tr, d):
    """One update of a 3D crack point at the jump j (3,) [m] in its frame (t1, t2, n): the law of
    :func:`return_trial` on the plane of the tangential trial traction (isotropic in the crack's
    plane: |T_t| for T_t, the slip along the trial's direction e), st_new, the traction tr (3,) [Pa]
    and the tangent d (3, 3) [Pa/m]: the 2D tangent along e and n, and |T_t| / |T_t,tr| kt across e
    (a trial turning in the plane turns the traction). Exactly the 2D law where T_t2 = 0."""
    for k in range(st_old.shape[0]):
        st_new[k] = st_old[k]
    t1 = st_old[C3_T0] + kt * (j[0] - st_old[C3_JP])
    t2 = st_old[C3_T0 + 1] + kt * (j[1] - st_old[C3_JP + 1])
    tn_tr = st_old[C3_T0 + 2] + kn * (j[2] - st_old[C3_JP + 2])
    rho = math.sqrt(t1 * t1 + t2 * t2)
    e1, e2 = (t1 / rho, t2 / rho) if rho > 0.0 else (1.0, 0.0)
    res = np.empty(7)
    d2 = np.empty((2, 2))
    status = return_trial(rho, tn_tr, 1.0, st_old[C3_GAMMA], st_old[C3_CP], st_old[C3_MODE], law, kt, kn, res, d2)
    t_t, t_n, gamma, psi, dz, dl, mode = res[0], res[1], res[2], res[3], res[4], res[5], res[6]
    tr[0], tr[1], tr[2] = t_t * e1, t_t * e2, t_n
    across = t_t / rho * kt if rho > 0.0 else d2[0, 0]  # the stiffness of a turning trial
    e = (e1, e2)
    for a in range(2):
        for b in range(2):
            dab = e[a] * e[b]
            d[a, b] = d2[0, 0] * dab + across * ((1.0 if a == b else 0.0) - dab)
        d[a, 2] = d2[0, 1] * e[a]
        d[2, a] = d2[1, 0] * e[a]
    d[2, 2] = d2[1, 1]
    for k in range(3):
        st_new[C3_J + k] = j[k]
        st_new[C3_T + k] = tr[k]
    st_new[C3_DZ] = dz
    st_new[C3_MODE] = mode
    if mode == 0.0:
        return status
    cp = math.cos(psi)
    st_new[C3_JP] = st_old[C3_JP] + dz * cp * e1
    st_new[C3_JP + 1] = st_old[C3_JP + 1] + dz * cp * e2
    st_new[C3_JP + 2] = st_old[C3_JP + 2] + dz * math.sin(psi) + dl
    st_new[C3_GAMMA] = gamma
    st_new[C3_ZETA] = st_old[C3_ZETA] + dz
    return status


@kernel
def crack_point_update_3d(j, st_old, law, kt, kn):
    """:func:`crack_return_3d` from Python (tests): (status, new state, traction (3,), tangent (3, 3))."""
    st_new = np.empty(st_old.shape[0])
    tr = np.empty(3)
    d = np.empty((3, 3))
    status = crack_return_3d(j, st_old, law, kt, kn, st_new, tr, d)
    return status, st_new, tr, d


def initial_state_3d(traction: np.ndarray, c_p: float) -> np.ndarray:
    """A 3D crack point's state when its cell is cut: the stress's traction (t1, t2, n) [Pa] on the
    new surface, no jump yet, and its peak cohesion c_p [Pa]."""
    st = np.zeros(N_C3)
    st[C3_T0:C3_T0 + 3] = traction
    st[C3_T:C3_T + 3] = traction
    st[C3_CP] = c_p
    return st
