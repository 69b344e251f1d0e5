"""Closed-form responses of the paper's specimen (homogeneous stress), for checks and reports.

Plane strain, lateral pressure p (sigma_xx = -p), axial stress sigma_yy = -q, specimen W x H,
crack at angle theta from horizontal with t = (cos, sin), n = (-sin, cos). Forces per unit
thickness [N/m], compression positive.
"""

from __future__ import annotations

import math

from scipy.optimize import brentq


def plane_strain_modulus(E: float, nu: float) -> float:
    """E' = E / (1 - nu^2) [Pa]."""
    return E / (1.0 - nu * nu)


def elastic_force(u: float, p: float, E: float, nu: float, width: float, height: float) -> float:
    """Axial force of the uncracked block at top shortening u: W (E' u / H + nu/(1-nu) p)."""
    return width * (plane_strain_modulus(E, nu) * u / height + nu / (1.0 - nu) * p)


def crack_tractions(q: float, p: float, theta: float) -> tuple[float, float]:
    """Local tractions (T_t, T_n) [Pa] on the crack plane under sigma = diag(-p, -q)."""
    s, c = math.sin(theta), math.cos(theta)
    return (p - q) * s * c, -p * s * s - q * c * c


def yield_value(q: float, p: float, theta: float, chi: float, coh: float, tan_phi: float) -> float:
    """Eq. (18) on the crack plane: sqrt(T_t^2 + (c - chi tan phi)^2) - (c - T_n tan phi) [Pa]."""
    tt, tn = crack_tractions(q, p, theta)
    return math.hypot(tt, coh - chi * tan_phi) - (coh - tn * tan_phi)


def strength_force(p: float, theta: float, chi: float, coh: float, tan_phi: float, width: float) -> float:
    """Axial force W q at which the crack plane reaches F = 0 for the given strengths (q >= p).

    With zero strengths it is p W: the residual of a crack with no shear strength.
    """
    f = lambda q: yield_value(q, p, theta, chi, coh, tan_phi)  # noqa: E731
    if f(p) >= 0.0:
        return p * width
    hi = 2.0 * p + 10.0 * (coh + chi) + 1.0
    while f(hi) < 0.0:
        hi *= 2.0
    return width * brentq(f, p, hi, xtol=1e-12, rtol=1e-14)


def mohr_coulomb_force(p: float, theta: float, coh: float, tan_phi: float, width: float) -> float:
    """Activation force W q of a Mohr-Coulomb plane (cone, no cap) under confinement p."""
    s, c = math.sin(theta), math.cos(theta)
    return width * (coh + p * (s * c + s * s * tan_phi)) / (s * c - c * c * tan_phi)


def series_slope(E: float, nu: float, width: float, height: float, kn: float, kt: float, theta: float) -> float:
    """Pre-peak dF/du [N/m per m] of bulk in series with a penalty crack of stiffness (kt, kn).

    Shortening per unit axial stress: H/E' from the bulk, sin^2 cos / kt + cos^3 / kn from the
    vertical component of the crack's elastic jump.
    """
    s, c = math.sin(theta), math.cos(theta)
    compliance = height / plane_strain_modulus(E, nu) + s * s * c / kt + c**3 / kn
    return width / compliance


def penalty_rule(e_plane: float, length: float, accuracy: float = 0.01) -> float:
    """Smallest penalty [Pa/m] whose artificial compliance stays below ``accuracy`` of the bulk's:
    k >= E' / (accuracy L) (the rule of thumb this study supports)."""
    return e_plane / (accuracy * length)
