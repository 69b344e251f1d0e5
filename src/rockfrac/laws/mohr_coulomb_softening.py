"""Mohr-Coulomb traction law of the embedded discontinuity with exponential softening (paper Sect. 4.1).

F = |T_t| - (c - T_n* tan(phi)), G = |T_t| - (c - T_n* tan(psi)), T_n* = min(T_n, 0);
c = c_r + (c_p - c_r) exp(-alpha_c gamma), phi = phi_r + (phi_p - phi_r) exp(-alpha_phi gamma),
psi = psi_p exp(-alpha_psi gamma), gamma = int cos(psi) d(zeta) [m]; the jump [[u]] = zeta m with
m = cos(psi) t + sin(psi) n = dG/dT / |dG/dT| (t oriented along the slip). The alpha_* are in 1/m.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rockfrac.compiled import inner, kernel

P_C_P, P_C_R, P_PHI_P, P_PHI_R, P_PSI_P, P_A_C, P_A_PHI, P_A_PSI = range(8)
N_PARAMS = 8


@dataclass(frozen=True)
class EmbeddedLaw:
    """Sect. 4.1 parameters: strengths [Pa], angles [rad], softening rates [1/m]; c_p None: eq. (28)."""

    c_r: float
    phi_p: float
    phi_r: float
    psi_p: float
    alpha_c: float
    alpha_phi: float
    alpha_psi: float
    c_p: float | None = None

    def as_array(self, c_p: float | None = None) -> np.ndarray:
        """Parameter vector; c_p overrides the law's own (eq. 28 per element)."""
        p = np.zeros(N_PARAMS)
        p[P_C_P] = self.c_p if c_p is None else c_p
        p[P_C_R], p[P_PHI_P], p[P_PHI_R], p[P_PSI_P] = self.c_r, self.phi_p, self.phi_r, self.psi_p
        p[P_A_C], p[P_A_PHI], p[P_A_PSI] = self.alpha_c, self.alpha_phi, self.alpha_psi
        return p


@kernel
def strengths(gamma, c_p, p):
    """(c [Pa], tan phi, psi [rad]) and their gamma-derivatives (dc [Pa/m], dtan phi [1/m], dpsi [1/m])."""
    e_c = math.exp(-p[P_A_C] * gamma)
    e_phi = math.exp(-p[P_A_PHI] * gamma)
    e_psi = math.exp(-p[P_A_PSI] * gamma)
    c_r = min(p[P_C_R], c_p)
    c = c_r + (c_p - c_r) * e_c
    phi = p[P_PHI_R] + (p[P_PHI_P] - p[P_PHI_R]) * e_phi
    psi = p[P_PSI_P] * e_psi
    tphi = math.tan(phi)
    dc = -p[P_A_C] * (c_p - c_r) * e_c
    dphi = -p[P_A_PHI] * (p[P_PHI_P] - p[P_PHI_R]) * e_phi
    dtphi = dphi * (1.0 + tphi * tphi)
    dpsi = -p[P_A_PSI] * psi
    return c, tphi, psi, dc, dtphi, dpsi


@inner
def gamma_of(dzeta, gamma_n, p):
    """gamma = gamma_n + cos(psi(gamma)) dzeta (backward Euler of gamma' = cos(psi) zeta') and d gamma/d dzeta."""
    g = gamma_n + math.cos(p[P_PSI_P] * math.exp(-p[P_A_PSI] * gamma_n)) * dzeta
    for _ in range(50):
        psi = p[P_PSI_P] * math.exp(-p[P_A_PSI] * g)
        res = g - gamma_n - math.cos(psi) * dzeta
        dres = 1.0 - math.sin(psi) * p[P_A_PSI] * psi * dzeta  # d/dg of -cos(psi) = sin(psi) dpsi/dg
        step = res / dres
        g -= step
        if abs(step) <= 1e-15 * (abs(g) + 1e-30):
            break
    psi = p[P_PSI_P] * math.exp(-p[P_A_PSI] * g)
    return g, math.cos(psi) / (1.0 - math.sin(psi) * p[P_A_PSI] * psi * dzeta)


def integrate_softening(law: EmbeddedLaw, c_p: float, zeta: np.ndarray) -> np.ndarray:
    """Reference: c along zeta from the ODE d gamma/d zeta = cos(psi(gamma)) (RK4 on a fine grid)."""
    grid = np.linspace(0.0, float(np.max(zeta)), 20001)
    g = np.zeros_like(grid)
    f = lambda gg: math.cos(law.psi_p * math.exp(-law.alpha_psi * gg))  # noqa: E731
    for i in range(1, grid.size):
        h = grid[i] - grid[i - 1]
        k1 = f(g[i - 1])
        k2 = f(g[i - 1] + 0.5 * h * k1)
        k3 = f(g[i - 1] + 0.5 * h * k2)
        k4 = f(g[i - 1] + h * k3)
        g[i] = g[i - 1] + h * (k1 + 2 * k2 + 2 * k3 + k4) / 6.0
    gamma = np.interp(zeta, grid, g)
    c_r = min(law.c_r, c_p)
    return c_r + (c_p - c_r) * np.exp(-law.alpha_c * gamma)
