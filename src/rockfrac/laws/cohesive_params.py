"""Parameter and state layouts of the cohesive traction law (paper Sect. 4.2).

Kernels are Numba functions on flat float64 arrays; these integer constants name the slots.
Local frame is ``(t, n)``; tractions in Pa, jumps in m, ``eps_*`` dimensionless.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

# --- parameter vector slots -------------------------------------------------------------
P_CT = 0  # tangential compliance 1/kt [m/Pa]; 0 for the rigid-plastic form
P_CN = 1  # normal compliance 1/kn [m/Pa]; 0 for the rigid-plastic form
P_GF1 = 2  # mode I fracture energy G_f^I [J/m^2], paired with opening (Carol et al. 1997)
P_GF2 = 3  # mode II fracture energy G_f^II [J/m^2], paired with slip
P_CHI_P = 4  # peak tensile strength [Pa]
P_CHI_R = 5  # residual tensile strength [Pa]
P_C_P = 6  # peak cohesion [Pa]
P_C_R = 7  # residual cohesion [Pa]
P_TANPHI_P = 8  # tan of peak friction angle
P_TANPHI_R = 9  # tan of residual friction angle
P_TANPSI_P = 10  # tan of peak dilation angle
P_A_CHI = 11  # softening rate of chi (dimensionless)
P_A_C = 12  # softening rate of c
P_A_PHI = 13  # softening rate of tan(phi)
P_A_PSI = 14  # softening rate of tan(psi)
P_THETA = 15  # weight of the start-of-flow traction in the work increment: 0 backward Euler, 1/2 trapezoidal
N_PARAMS = 16

WORK_RULES = {"backward_euler": 0.0, "trapezoidal": 0.5}  # work_rule -> P_THETA

# --- state vector slots (per integration point) ------------------------------------------
S_TT = 0  # tangential traction T_t [Pa]
S_TN = 1  # normal traction T_n [Pa]
S_UPT = 2  # plastic jump, tangential [m]
S_UPN = 3  # plastic jump, normal [m]
S_EPSN = 4  # eps_n^p, opening work / G_f^I
S_EPSS = 5  # eps_s^p, slip work / G_f^II
S_DGAMMA = 6  # Delta gamma of the last update [m]
S_MODE = 7  # 0 elastic / constrained, 1 plastic
N_STATE = 8

MODE_ELASTIC = 0.0
MODE_PLASTIC = 1.0


@dataclass(frozen=True)
class CohesiveLaw:
    """Table-1 style parameters of the tension-capped hyperbolic Mohr-Coulomb law (SI, radians)."""

    GfI: float
    GfII: float
    chi_p: float
    chi_r: float
    c_p: float
    c_r: float
    phi_p: float
    phi_r: float
    psi_p: float
    alpha_chi: float
    alpha_c: float
    alpha_phi: float
    alpha_psi: float
    kn: float | None = None  # None (or inf) -> rigid-plastic form
    kt: float | None = None
    work_rule: str = "backward_euler"  # or "trapezoidal" (see rockfrac.laws.cohesive)

    def __post_init__(self) -> None:
        rule = getattr(self.work_rule, "value", self.work_rule)
        if rule not in WORK_RULES:
            raise ValueError(f"work_rule must be one of {sorted(WORK_RULES)}, got {self.work_rule!r}")
        object.__setattr__(self, "work_rule", rule)

    @property
    def rigid(self) -> bool:
        return self.kn is None or self.kt is None or math.isinf(self.kn) or math.isinf(self.kt)

    def softening_modulus(self) -> float:
        """Upper estimate [Pa/m] of the steepest softening slope dF/d[[u^p]] at the peak.

        Opening: (alpha_chi dchi + alpha_c dc) chi_p / G_f^I; slip: (alpha_c dc + alpha_chi dchi
        tan phi_p) c_p / G_f^II plus the friction loss alpha_phi dtan(phi) |T_n| c_p / G_f^II with
        |T_n| ~ max(chi_p, c_p / tan phi_p). A return map with stiffness k is unique when k exceeds it.
        """
        d_chi, d_c = self.chi_p - self.chi_r, self.c_p - self.c_r
        tp, d_tp = math.tan(self.phi_p), math.tan(self.phi_p) - math.tan(self.phi_r)
        t_n = max(self.chi_p, self.c_p / tp if tp > 0 else self.chi_p)
        opening = (self.alpha_chi * d_chi + self.alpha_c * d_c) * self.chi_p / self.GfI
        slip = ((self.alpha_c * d_c + self.alpha_chi * d_chi * tp) * self.c_p
                + self.alpha_phi * d_tp * t_n * self.c_p) / self.GfII
        return max(opening, slip)

    def as_array(self) -> np.ndarray:
        p = np.zeros(N_PARAMS)
        if self.kt is not None and self.kn is not None and not self.rigid:
            p[P_CT] = 1.0 / self.kt
            p[P_CN] = 1.0 / self.kn
        p[P_GF1] = self.GfI
        p[P_GF2] = self.GfII
        p[P_CHI_P] = self.chi_p
        p[P_CHI_R] = self.chi_r
        p[P_C_P] = self.c_p
        p[P_C_R] = self.c_r
        p[P_TANPHI_P] = math.tan(self.phi_p)
        p[P_TANPHI_R] = math.tan(self.phi_r)
        p[P_TANPSI_P] = math.tan(self.psi_p)
        p[P_A_CHI] = self.alpha_chi
        p[P_A_C] = self.alpha_c
        p[P_A_PHI] = self.alpha_phi
        p[P_A_PSI] = self.alpha_psi
        p[P_THETA] = WORK_RULES[self.work_rule]
        return p


def initial_state(n_points: int) -> np.ndarray:
    """Virgin state for ``n_points`` integration points, shape (n_points, N_STATE)."""
    return np.zeros((n_points, N_STATE))
