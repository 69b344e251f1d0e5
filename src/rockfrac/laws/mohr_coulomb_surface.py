"""The paper's traction law as a plug-in: the tension-capped hyperbolic Mohr-Coulomb surface with
work softening of Carol, Prat & Lopez (1997), paper Sect. 4.2 (the pointwise kernels are in
:mod:`rockfrac.laws.cohesive`, the parameter layout in :mod:`rockfrac.laws.cohesive_params`).

At the start of a step (zero jump increment) a point that was plastic in the committed state keeps
its committed traction and consistent tangent, so the first Newton iteration of a softening step
predicts continued plastic flow instead of an elastic (or rigid) response.
"""

from __future__ import annotations

from enum import Enum

import numba as nb
import numpy as np
from pydantic import Field, model_validator

from rockfrac.compiled import inner, kernel
from rockfrac.fem.interface import (
    CHUNK,
    junction_rows,
    local_jump,
    multiplier_rows,
    pair_blocks_local,
)
from rockfrac.laws import cohesive_surface as _law
from rockfrac.laws.cohesive import (
    elastic_update,
    ep_rescued_jump,
    ep_update,
    ep_update_jump,
    rescued_step,
    return_step,
)
from rockfrac.laws.cohesive_params import (
    MODE_PLASTIC,
    S_DGAMMA,
    S_EPSN,
    S_EPSS,
    S_MODE,
    S_TN,
    S_TT,
    CohesiveLaw,
)
from rockfrac.laws.cohesive_solve import workspace
from rockfrac.laws.cohesive_system import START_CROSSING, START_GIVEN, START_NONE
from rockfrac.laws.traction_law import TractionLaw, hold_constrained, keep_committed
from rockfrac.threads import parallel_kernel
from rockfrac.values import Angle, Energy, Rate, Section, Strength


class WorkRule(str, Enum):
    backward_euler = "backward_euler"
    trapezoidal = "trapezoidal"


class MohrCoulombParameters(Section):
    """Parameters of the traction law of Sect. 4.2 (Table 1 symbols)."""

    GfI: Energy = Field(description="mode I fracture energy [J/m^2]")
    GfII: Energy = Field(description="mode II fracture energy [J/m^2]")
    chi_p: Strength = Field(description="peak tensile strength [Pa]")
    chi_r: Strength = Field(description="residual tensile strength [Pa]")
    c_p: Strength = Field(description="peak cohesion [Pa]")
    c_r: Strength = Field(description="residual cohesion [Pa]")
    phi_p: Angle = Field(description="peak friction angle [rad]")
    phi_r: Angle = Field(description="residual friction angle [rad]")
    psi_p: Angle = Field(description="peak dilation angle [rad]")
    alpha_chi: Rate = Field(description="softening rate of chi [-]")
    alpha_c: Rate = Field(description="softening rate of c [-]")
    alpha_phi: Rate = Field(description="softening rate of tan(phi) [-]")
    alpha_psi: Rate = Field(description="softening rate of tan(psi) [-]")
    work_rule: WorkRule = Field(WorkRule.backward_euler, strict=False, description="work that drives softening in "
                                "a step: 'backward_euler' (the paper's: end traction x plastic jump increment; "
                                "first order in the step) or 'trapezoidal' (mean of the traction where flow starts "
                                "and the end traction; second order)")

    @model_validator(mode="after")
    def _residual_below_peak(self):
        if self.chi_r > self.chi_p or self.c_r > self.c_p or self.phi_r > self.phi_p:
            raise ValueError("residual values (chi_r, c_r, phi_r) must not exceed the peak ones")
        return self


@parallel_kernel(cost=1.4e-6)  # s per item, one thread (benchmarks/thread_rule.py)
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
            du_t, du_n = local_jump(r, djump[i])
            if du_t == 0.0 and du_n == 0.0 and s_old[i, S_MODE] == MODE_PLASTIC:
                keep_committed(s_old[i], d_old[i], s_new[i], d_new[i], S_DGAMMA)
                status[i] = 1
            else:
                status[i] = ep_update_jump(du_t, du_n, s_old[i], p, s_new[i], d_new[i], wk)
            pair_blocks_local(r, weight[i], s_new[i, S_TT], s_new[i, S_TN], d_new[i], fe[i], ke[i])


@kernel
def ep_rescue_points(index, frame, weight, djump, s_old, p, s_new, d_new, fe, ke, status):
    """The points ``index`` of :func:`ep_points` whose return failed, again with the rescued return
    (:func:`rockfrac.laws.cohesive.rescued_step`): compiled only when a run first needs it."""
    wk = workspace()
    for i in index:
        r = frame[i]
        du_t, du_n = local_jump(r, djump[i])
        status[i] = ep_rescued_jump(du_t, du_n, s_old[i], p, s_new[i], d_new[i], wk)
        pair_blocks_local(r, weight[i], s_new[i, S_TT], s_new[i, S_TN], d_new[i], fe[i], ke[i])


@inner
def _rp_return_start(r, lam_i, s_old_i, p):
    """The return's T_old := lambda (local frame) [Pa] and the work rule's start: the flow starts at
    the committed traction of a committed plastic point, or of a constrained one already on its
    yield surface (a step that starts at the activation); from inside, the rigid traction's path to
    the surface is not defined and the onset step is backward Euler."""
    lam_t = r[0, 0] * lam_i[0] + r[0, 1] * lam_i[1]
    lam_n = r[1, 0] * lam_i[0] + r[1, 1] * lam_i[1]
    on_surface = (s_old_i[S_MODE] == MODE_PLASTIC
                  or _law.yield_function(s_old_i[S_TT], s_old_i[S_TN], s_old_i[S_EPSN], s_old_i[S_EPSS], p)
                  >= -_law.elastic_tolerance(p))
    return lam_t, lam_n, START_GIVEN if on_surface else START_NONE


@inner
def _rp_blocks(i, frame, weight, lam, aug, eps, mode_prev, s_new, d_new, fe, ke, switched):
    """Point i's switch flag and element blocks from its updated state."""
    r = frame[i]
    switched[i] = 1 if s_new[i, S_MODE] != mode_prev[i] else 0
    fi = fe[i]
    ki = ke[i]
    pair_blocks_local(r, weight[i], s_new[i, S_TT], s_new[i, S_TN], d_new[i], fi, ki)
    multiplier_rows(r, weight[i], s_new[i, S_TT], s_new[i, S_TN], lam[i], aug, fi, ki)
    if eps[i] > 0.0 and s_new[i, S_MODE] != MODE_PLASTIC:
        junction_rows(weight[i], eps[i], ki, 2)


@inner
def _rp_point(i, frame, weight, djump, lam, aug, eps, pinned, s_old, d_old, mode_prev, p, s_new, d_new, fe, ke,
              status, switched, wk):
    """Point i of :func:`rp_points`."""
    r = frame[i]
    h_t, h_n = local_jump(r, djump[i])
    if h_t == 0.0 and h_n == 0.0 and s_old[i, S_MODE] == MODE_PLASTIC and not pinned[i]:
        keep_committed(s_old[i], d_old[i], s_new[i], d_new[i], S_DGAMMA)
        status[i] = 1
    elif pinned[i]:  # the constrained branch of eq. (33): T = lambda + r h, D = r I
        hold_constrained(s_old[i], s_new[i], d_new[i], r[0, 0] * lam[i, 0] + r[0, 1] * lam[i, 1] + aug * h_t,
                         r[1, 0] * lam[i, 0] + r[1, 1] * lam[i, 1] + aug * h_n, aug, S_DGAMMA, S_MODE)
        status[i] = 0
    else:  # trial lambda + r h: elastic, or the return
        lam_t, lam_n, start = _rp_return_start(r, lam[i], s_old[i], p)
        comp = 1.0 / aug
        status[i] = return_step(h_t, h_n, lam_t, lam_n, s_old[i, S_TT], s_old[i, S_TN], start, comp, comp,
                                s_old[i], p, s_new[i], d_new[i], wk)
    _rp_blocks(i, frame, weight, lam, aug, eps, mode_prev, s_new, d_new, fe, ke, switched)


@parallel_kernel(cost=1.4e-6)  # s per item, one thread (benchmarks/thread_rule.py)
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
    perturbed-Lagrangian weight of constrained junction pairs (0 elsewhere; the kernel writes its matrix
    term only), see CohesiveRP.
    pinned (n,): held constrained in this iteration whatever their trial (active-set pinning, see
    CohesiveRP).
    """
    n = frame.shape[0]
    for c in nb.prange((n + CHUNK - 1) // CHUNK):
        wk = workspace()  # one scratch per chunk: a plastic point allocates nothing
        for i in range(c * CHUNK, min(n, (c + 1) * CHUNK)):
            _rp_point(i, frame, weight, djump, lam, aug, eps, pinned, s_old, d_old, mode_prev, p, s_new, d_new,
                      fe, ke, status, switched, wk)


@kernel
def rp_rescue_points(index, frame, weight, djump, lam, aug, eps, s_old, mode_prev, p, s_new, d_new, fe, ke, status,
                     switched):
    """The points ``index`` of :func:`rp_points` whose return failed, again with the rescued return
    (:func:`rockfrac.laws.cohesive.rescued_step`, K^e = r I): compiled only when a run first needs it."""
    wk = workspace()
    comp = 1.0 / aug
    for i in index:
        r = frame[i]
        h_t, h_n = local_jump(r, djump[i])
        lam_t, lam_n, start = _rp_return_start(r, lam[i], s_old[i], p)
        status[i] = rescued_step(h_t, h_n, lam_t, lam_n, s_old[i, S_TT], s_old[i, S_TN], start, comp, comp,
                                 s_old[i], p, s_new[i], d_new[i], wk)
        _rp_blocks(i, frame, weight, lam, aug, eps, mode_prev, s_new, d_new, fe, ke, switched)


@kernel
def yield_values(state, p):
    """F at the states' tractions (n,) [Pa]."""
    out = np.empty(state.shape[0])
    for i in range(state.shape[0]):
        out[i] = _law.yield_function(state[i, S_TT], state[i, S_TN], state[i, S_EPSN], state[i, S_EPSS], p)
    return out


@kernel
def trial_return(tr_t, tr_n, ct, cn, s_old, p, s_new, D):
    """The EP return (eq. 31) from the trial (tr_t, tr_n) [Pa], K^e = diag(1/ct, 1/cn), T_old = s_old's
    traction (du = C (T^tr - T_old)), D = dT/d(du) [Pa/m]: a function of the trial alone when P_THETA = 0."""
    if _law.yield_function(tr_t, tr_n, s_old[S_EPSN], s_old[S_EPSS], p) <= _law.elastic_tolerance(p):
        return elastic_update(tr_t, tr_n, ct, cn, s_old, s_new, D)  # only a yielding point allocates
    t_t, t_n = s_old[S_TT], s_old[S_TN]
    return rescued_step((tr_t - t_t) * ct, (tr_n - t_n) * cn, t_t, t_n, t_t, t_n, np.int64(START_CROSSING), ct, cn,
                        s_old, p, s_new, D, workspace())


class MohrCoulombSurface(TractionLaw):
    """The tension-capped hyperbolic Mohr-Coulomb law with work softening (paper Sect. 4.2)."""

    name = "mohr_coulomb"
    summary = "tension-capped hyperbolic Mohr-Coulomb surface, exponential work softening (paper Sect. 4.2)"
    Parameters = MohrCoulombParameters
    state_names = ("T_t", "T_n", "jump_p_t", "jump_p_n", "eps_n_p", "eps_s_p", "dgamma", "mode")
    mode_slot = S_MODE
    dgamma_slot = S_DGAMMA
    record_names = ("eps_n_p", "eps_s_p", "chi", "c", "tan_phi", "tan_psi")
    tensile_record = "chi"  # the tensile strength: F = 0 at T_t = 0, T_n = chi (eq. 18)
    ep_kernel = ep_points
    rescue_kernel = ep_rescue_points
    rp_rescue_kernel = rp_rescue_points
    rp_kernel = rp_points
    trial_kernel = trial_return

    def __init__(self, params: MohrCoulombParameters, kn: float | None = None, kt: float | None = None):
        self.law = CohesiveLaw(**{k: getattr(params, k) for k in CohesiveLaw.__dataclass_fields__
                                  if k not in ("kn", "kt")}, kn=kn, kt=kt)
        super().__init__(params, kn, kt)

    @property
    def scale(self) -> float:
        return max(self.law.c_p, self.law.chi_p, 1.0)

    def vector(self) -> np.ndarray:
        return self.law.as_array()

    def drive(self, jumps: np.ndarray) -> dict[str, np.ndarray]:
        from rockfrac.laws.drive import drive_path

        return drive_path(self.law, jumps)

    def records(self, state: np.ndarray) -> dict[str, np.ndarray]:
        q = _law.strengths_points(np.ascontiguousarray(state[:, S_EPSN]), np.ascontiguousarray(state[:, S_EPSS]),
                                  self.p)
        return {"eps_n_p": state[:, S_EPSN], "eps_s_p": state[:, S_EPSS], "chi": q[:, 0], "c": q[:, 1],
                "tan_phi": q[:, 2], "tan_psi": q[:, 3]}

    def flow(self, state: np.ndarray) -> np.ndarray:
        return _law.flow_points(np.ascontiguousarray(state[:, S_TT]), np.ascontiguousarray(state[:, S_TN]),
                                np.ascontiguousarray(state[:, S_EPSN]), np.ascontiguousarray(state[:, S_EPSS]),
                                self.p)

    def yield_values(self, state: np.ndarray) -> np.ndarray:
        return yield_values(np.ascontiguousarray(state), self.p)

    def dissipation(self, state: np.ndarray) -> np.ndarray:
        """G_f^I eps_n^p + G_f^II eps_s^p: the opening and slip work the law has counted [J/m^2]."""
        return self.law.GfI * state[:, S_EPSN] + self.law.GfII * state[:, S_EPSS]

    def softening_modulus(self) -> float:
        return self.law.softening_modulus()


__all__ = ["MohrCoulombParameters", "MohrCoulombSurface", "WorkRule", "ep_points", "ep_update", "rp_points",
           "rp_rescue_points", "trial_return"]
