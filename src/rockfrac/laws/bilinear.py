"""A bilinear mixed-mode cohesive law (Camacho & Ortiz 1996 family), as plasticity: the whole
plug-in (parameters, state, point update and tangent, point loops) in one module.

Effective traction ``t = sqrt(<T_n>^2 + T_t^2 / beta^2)`` (compression does not open the crack; beta
is the ratio of the shear to the tensile strength), yield function ``F = t - s(kappa)`` with the
strength falling linearly with the effective plastic opening ``kappa`` (the accumulated
``sqrt(d[[u^p_n]]^2 + beta^2 d[[u^p_t]]^2)``):

    s(kappa) = sigma_c (1 - kappa / delta_c) for kappa < delta_c, 0 beyond; delta_c = 2 G_c / sigma_c,

and associated flow ``d[[u^p]] = dgamma dF/dT`` (so ``dkappa = dgamma``). With the penalty (EP) the
traction-separation curve in pure opening is the bilinear one: elastic slope kn up to sigma_c,
then linear softening to zero at a plastic opening delta_c; rigid-plastic (RP) it is the extrinsic
law, rigid up to sigma_c. The energy dissipated to full separation is G_c in every mode: in pure
shear the traction beta s(kappa) works on a plastic slip kappa / beta (peak beta sigma_c, softening
slope beta^2 sigma_c / delta_c). Unloading is elastic (the plastic
opening stays). A fully failed point carries no tension and no shear; in compression it is in
frictionless contact (T_n = kn [[u_n]]^e <= 0, or the multiplier for RP).

The return mapping reduces to one scalar equation in dgamma, solved by a bracketed Newton iteration
(the strength's piecewise-linear softening makes every other unknown explicit); its consistent
tangent comes from the 3 x 3 linearisation at the converged point.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np
from pydantic import Field

from rockfrac.compiled import inner, kernel
from rockfrac.fem.interface import (
    CHUNK,
    junction_rows,
    local_jump,
    multiplier_rows,
    pair_blocks_local,
)
from rockfrac.laws.traction_law import MODE_PLASTIC, TractionLaw, hold_constrained, keep_committed
from rockfrac.threads import parallel_kernel
from rockfrac.values import Energy, Section, Strength

# parameter vector
P_CT, P_CN, P_SIGMA, P_DELTA, P_BETA = 0, 1, 2, 3, 4
N_PARAMS = 5
# state
S_TT, S_TN, S_UPT, S_UPN, S_KAPPA, S_DGAMMA, S_MODE = 0, 1, 2, 3, 4, 5, 6
N_STATE = 7

FAIL = -1
MAX_ITERATIONS = 60


class BilinearParameters(Section):
    """Tensile strength, fracture energy and shear-to-tension strength ratio."""

    sigma_c: Strength = Field(gt=0, description="tensile strength [Pa]")
    Gc: Energy = Field(description="mode I fracture energy [J/m^2]: the area under the softening branch")
    beta: float = Field(1.0, gt=0, le=1e3, description="shear strength / tensile strength [-] (every mode "
                        "dissipates Gc)")


@inner
def strength(kappa, p):
    """s(kappa) [Pa]."""
    if kappa >= p[P_DELTA]:
        return 0.0
    return p[P_SIGMA] * (1.0 - kappa / p[P_DELTA])


@inner
def effective(tt, tn, beta):
    """t = sqrt(<T_n>^2 + T_t^2 / beta^2) [Pa]."""
    pos = max(0.0, tn)
    return math.sqrt(pos * pos + tt * tt / (beta * beta))


@inner
def _opening_return(tr_t, tr_n, kt, kn, kappa, p, d_cap):
    """Plastic return with tr_n > 0, 0 < dgamma < d_cap: returns (dgamma, T_t, T_n, status)."""
    beta2 = p[P_BETA] * p[P_BETA]
    slope = p[P_SIGMA] / p[P_DELTA]
    lo, hi = 0.0, d_cap
    dg = 0.0
    t_tr = effective(tr_t, tr_n, p[P_BETA])
    s0 = strength(kappa, p)
    # first guess: the radial return at the elastic slope of the larger stiffness
    k_eff = max(kt / beta2, kn)
    dg = min(0.5 * d_cap, max(0.0, (t_tr - s0) / (k_eff + slope)))
    for _ in range(MAX_ITERATIONS):
        s = strength(kappa + dg, p)
        a_t = kt * dg / (beta2 * s)
        a_n = kn * dg / s
        tt = tr_t / (1.0 + a_t)
        tn = tr_n / (1.0 + a_n)
        t = math.sqrt(tn * tn + tt * tt / beta2)
        psi = t - s
        if abs(psi) <= 1e-13 * p[P_SIGMA]:
            return dg, tt, tn, 0
        if psi > 0.0:
            lo = dg
        else:
            hi = dg
        g = (s + dg * slope) / (s * s)  # d(dg / s) / d dg
        d_tn = -tn / (1.0 + a_n) * kn * g
        d_tt = -tt / (1.0 + a_t) * kt / beta2 * g
        d_psi = (tn * d_tn + tt * d_tt / beta2) / t + slope
        step = dg - psi / d_psi if d_psi > 0.0 else 0.5 * (lo + hi)
        dg = step if lo < step < hi else 0.5 * (lo + hi)
    return dg, tr_t, tr_n, FAIL


@kernel
def return_map(tr_t, tr_n, ct, cn, s_old, p, s_new, D):
    """The state at the trial traction (tr_t, tr_n) = T_old + K d[[u]] (EP; K = diag(1/ct, 1/cn)) or
    lambda + r h (RP; ct = cn = 1/r), and the consistent tangent D = dT / d[[u]] (2, 2). Returns 0
    (elastic), 1 (plastic) or FAIL (no unique return: the penalty is below the softening slope)."""
    kt, kn = 1.0 / ct, 1.0 / cn
    beta = p[P_BETA]
    beta2 = beta * beta
    kappa = s_old[S_KAPPA]
    for k in range(s_old.shape[0]):  # a loop, not a slice copy: no shape-error path to compile
        s_new[k] = s_old[k]
    s_new[S_DGAMMA] = 0.0
    D[:, :] = 0.0
    t_tr = effective(tr_t, tr_n, beta)
    s0 = strength(kappa, p)
    if s0 > 0.0 and t_tr <= s0 * (1.0 + 1e-12):
        s_new[S_TT], s_new[S_TN], s_new[S_MODE] = tr_t, tr_n, 0.0
        D[0, 0], D[1, 1] = kt, kn
        return 0
    # every tension and shear released: a fully failed point (contact in compression)
    dup_t = tr_t * ct
    dup_n = tr_n * cn if tr_n > 0.0 else 0.0
    dk_full = math.sqrt(dup_n * dup_n + beta2 * dup_t * dup_t)
    d_cap = p[P_DELTA] - kappa
    s_new[S_MODE] = MODE_PLASTIC if dk_full > 0.0 else 0.0
    if dk_full >= d_cap:
        s_new[S_TT] = 0.0
        s_new[S_TN] = min(0.0, tr_n)
        s_new[S_UPT] += dup_t
        s_new[S_UPN] += dup_n
        s_new[S_KAPPA] = kappa + dk_full
        s_new[S_DGAMMA] = dk_full
        D[1, 1] = kn if tr_n < 0.0 else 0.0
        return 1
    slope = p[P_SIGMA] / p[P_DELTA]
    if tr_n <= 0.0:  # shear under compression: T_n = tr_n, |T_t| = beta s, linear in dgamma
        den = kt / beta - beta * slope
        if den <= 0.0:
            return FAIL
        dg = (abs(tr_t) - beta * s0) / den
        sign = 1.0 if tr_t >= 0.0 else -1.0
        tt = sign * beta * strength(kappa + dg, p)
        s_new[S_TT], s_new[S_TN] = tt, tr_n
        s_new[S_UPT] += (tr_t - tt) * ct
        s_new[S_KAPPA] = kappa + dg
        s_new[S_DGAMMA] = dg
        D[0, 0] = -beta * slope / den * kt
        D[1, 1] = kn
        return 1
    if kn <= slope or kt / beta2 <= slope:
        return FAIL
    dg, tt, tn, status = _opening_return(tr_t, tr_n, kt, kn, kappa, p, d_cap)
    if status < 0:
        return FAIL
    s_new[S_TT], s_new[S_TN] = tt, tn
    s_new[S_UPT] += (tr_t - tt) * ct
    s_new[S_UPN] += (tr_n - tn) * cn
    s_new[S_KAPPA] = kappa + dg
    s_new[S_DGAMMA] = dg
    # consistent tangent: J d(T_t, T_n, dg) = d(tr_t, tr_n, 0), D = (J^-1)[:2, :2] K
    t = math.sqrt(tn * tn + tt * tt / beta2)
    j = np.empty((3, 3))
    j[0, 0] = 1.0 + kt * dg / (beta2 * t) * (1.0 - tt * tt / (beta2 * t * t))
    j[0, 1] = -kt * dg * tt * tn / (beta2 * t * t * t)
    j[0, 2] = kt * tt / (beta2 * t)
    j[1, 0] = -kn * dg * tn * tt / (beta2 * t * t * t)
    j[1, 1] = 1.0 + kn * dg / t * (1.0 - tn * tn / (t * t))
    j[1, 2] = kn * tn / t
    j[2, 0] = tt / (beta2 * t)
    j[2, 1] = tn / t
    j[2, 2] = slope
    inv = np.linalg.inv(j)
    D[0, 0], D[0, 1] = inv[0, 0] * kt, inv[0, 1] * kn
    D[1, 0], D[1, 1] = inv[1, 0] * kt, inv[1, 1] * kn
    return 1


@kernel
def trial_return(tr_t, tr_n, ct, cn, s_old, p, s_new, D):
    """:func:`return_map`, with FAIL where it raises (a singular tangent): the law's trial_kernel."""
    try:
        return return_map(tr_t, tr_n, ct, cn, s_old, p, s_new, D)
    except Exception:  # noqa: BLE001 (Numba catches no narrower class; np.linalg.inv's LinAlgError)
        return FAIL


@inner
def point_update(du, s_old, p, s_new, D):
    """One EP update of one point by the local jump increment du (2,) [m]."""
    return return_map(s_old[S_TT] + du[0] / p[P_CT], s_old[S_TN] + du[1] / p[P_CN], p[P_CT], p[P_CN], s_old, p,
                      s_new, D)


@parallel_kernel(cost=0.08e-6)  # s per item, one thread (benchmarks/thread_rule.py)
def ep_points(frame, weight, djump, s_old, d_old, p, s_new, d_new, fe, ke, status):
    """The EP form at every point (see rockfrac.laws.traction_law)."""
    n = frame.shape[0]
    for c in nb.prange((n + CHUNK - 1) // CHUNK):
        for i in range(c * CHUNK, min(n, (c + 1) * CHUNK)):
            r = frame[i]
            du_t, du_n = local_jump(r, djump[i])
            if du_t == 0.0 and du_n == 0.0 and s_old[i, S_MODE] == MODE_PLASTIC:
                keep_committed(s_old[i], d_old[i], s_new[i], d_new[i], S_DGAMMA)
                status[i] = 1
            else:
                status[i] = return_map(s_old[i, S_TT] + du_t / p[P_CT], s_old[i, S_TN] + du_n / p[P_CN], p[P_CT],
                                       p[P_CN], s_old[i], p, s_new[i], d_new[i])
            pair_blocks_local(r, weight[i], s_new[i, S_TT], s_new[i, S_TN], d_new[i], fe[i], ke[i])


@parallel_kernel(cost=0.1e-6)  # s per item, one thread (benchmarks/thread_rule.py)
def rp_points(frame, weight, djump, lam, aug, eps, pinned, s_old, d_old, mode_prev, p, s_new, d_new, fe, ke,
              status, switched):
    """The RP form at every point: the return at the augmented trial lambda + r h (see
    rockfrac.laws.mohr_coulomb_surface.rp_points for the augmented Lagrangian)."""
    n = frame.shape[0]
    comp = 1.0 / aug
    for c in nb.prange((n + CHUNK - 1) // CHUNK):
        for i in range(c * CHUNK, min(n, (c + 1) * CHUNK)):
            r = frame[i]
            w = weight[i]
            h_t, h_n = local_jump(r, djump[i])
            lam_t = r[0, 0] * lam[i, 0] + r[0, 1] * lam[i, 1]
            lam_n = r[1, 0] * lam[i, 0] + r[1, 1] * lam[i, 1]
            if h_t == 0.0 and h_n == 0.0 and s_old[i, S_MODE] == MODE_PLASTIC and not pinned[i]:
                keep_committed(s_old[i], d_old[i], s_new[i], d_new[i], S_DGAMMA)
                status[i] = 1
            elif pinned[i]:
                hold_constrained(s_old[i], s_new[i], d_new[i], lam_t + aug * h_t, lam_n + aug * h_n, aug, S_DGAMMA,
                                 S_MODE)
                status[i] = 0
            else:
                status[i] = return_map(lam_t + aug * h_t, lam_n + aug * h_n, comp, comp, s_old[i], p, s_new[i],
                                       d_new[i])
            switched[i] = 1 if s_new[i, S_MODE] != mode_prev[i] else 0
            pair_blocks_local(r, w, s_new[i, S_TT], s_new[i, S_TN], d_new[i], fe[i], ke[i])
            multiplier_rows(r, w, s_new[i, S_TT], s_new[i, S_TN], lam[i], aug, fe[i], ke[i])
            if eps[i] > 0.0 and s_new[i, S_MODE] != MODE_PLASTIC:
                junction_rows(w, eps[i], ke[i], 2)


@kernel
def drive_kernel(jumps, p, states):
    """States (n, N_STATE) along total local jumps (n, 2) from zero; returns the failing row or -1."""
    s = np.zeros(N_STATE)
    s_new = np.empty(N_STATE)
    d = np.empty((2, 2))
    du = np.empty(2)
    prev = np.zeros(2)
    for i in range(jumps.shape[0]):
        du[0], du[1] = jumps[i, 0] - prev[0], jumps[i, 1] - prev[1]
        if point_update(du, s, p, s_new, d) < 0:
            return i
        s[:] = s_new
        states[i, :] = s
        prev[0], prev[1] = jumps[i, 0], jumps[i, 1]
    return -1


class Bilinear(TractionLaw):
    """Bilinear mixed-mode softening (Camacho-Ortiz family) in plasticity form; see the module."""

    name = "bilinear"
    summary = "bilinear mixed-mode softening, strength sigma_c, fracture energy Gc, shear ratio beta"
    Parameters = BilinearParameters
    state_names = ("T_t", "T_n", "jump_p_t", "jump_p_n", "kappa", "dgamma", "mode")
    mode_slot = S_MODE
    dgamma_slot = S_DGAMMA
    record_names = ("kappa", "strength")
    tensile_record = "strength"
    ep_kernel = ep_points
    rp_kernel = rp_points
    trial_kernel = trial_return

    @property
    def delta_c(self) -> float:
        """The plastic opening at full separation [m]."""
        return 2.0 * self.params.Gc / self.params.sigma_c

    @property
    def scale(self) -> float:
        return self.params.sigma_c * max(1.0, self.params.beta)

    def vector(self) -> np.ndarray:
        p = np.zeros(N_PARAMS)
        if self.kt is not None and self.kn is not None:
            p[P_CT], p[P_CN] = 1.0 / self.kt, 1.0 / self.kn
        p[P_SIGMA], p[P_DELTA], p[P_BETA] = self.params.sigma_c, self.delta_c, self.params.beta
        return p

    def drive(self, jumps: np.ndarray) -> dict[str, np.ndarray]:
        if self.rigid:
            raise ValueError("the driver needs the EP form of the law: give finite kn and kt")
        jumps = np.ascontiguousarray(jumps, dtype=np.float64)
        states = np.zeros((jumps.shape[0], N_STATE))
        bad = drive_kernel(jumps, self.p, states)
        if bad >= 0:
            raise RuntimeError(f"bilinear law: no unique return at path step {bad + 1} (jump "
                               f"{jumps[bad].tolist()} m): the penalty is below the softening slope")
        out = {"step": np.arange(1, jumps.shape[0] + 1), "jump_t": jumps[:, 0].copy(), "jump_n": jumps[:, 1].copy()}
        out.update({name: states[:, k].copy() for k, name in enumerate(self.state_names[:4])})
        out.update(self.records(states))
        return out

    def records(self, state: np.ndarray) -> dict[str, np.ndarray]:
        kappa = state[:, S_KAPPA]
        return {"kappa": kappa, "strength": self.params.sigma_c * np.clip(1.0 - kappa / self.delta_c, 0.0, None)}

    def flow(self, state: np.ndarray) -> np.ndarray:
        tt, tn = state[:, S_TT], np.maximum(state[:, S_TN], 0.0)
        b2 = self.params.beta**2
        t = np.sqrt(tn**2 + tt**2 / b2)
        safe = np.where(t > 0.0, t, 1.0)
        return np.where(t[:, None] > 0.0, np.stack([tt / (b2 * safe), tn / safe], axis=1), 0.0)

    def yield_values(self, state: np.ndarray) -> np.ndarray:
        tt, tn = state[:, S_TT], np.maximum(state[:, S_TN], 0.0)
        t = np.sqrt(tn**2 + tt**2 / self.params.beta**2)
        return t - self.records(state)["strength"]

    def dissipation(self, state: np.ndarray) -> np.ndarray:
        """int_0^kappa s dk = sigma_c (kappa - kappa^2 / (2 delta_c)), G_c once separated [J/m^2]."""
        k = np.minimum(state[:, S_KAPPA], self.delta_c)
        return self.params.sigma_c * (k - k * k / (2.0 * self.delta_c))

    def softening_modulus(self) -> float:
        return max(1.0, self.params.beta**2) * self.params.sigma_c / self.delta_c
