"""Linear isotropic elasticity in Voigt form (xx, yy, zz, xy, yz, xz), engineering shear strains."""

from __future__ import annotations

import numpy as np

from rockfrac.fem.kinematics import VOIGT_2D


def lame(E: float, nu: float) -> tuple[float, float]:
    """Lame constants (lambda, mu) [Pa]."""
    return E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu)), E / (2.0 * (1.0 + nu))


def isotropic_elasticity(E: float, nu: float) -> np.ndarray:
    """Elasticity matrix (6, 6) [Pa]: sigma = D eps with engineering shear strains."""
    lam, mu = lame(E, nu)
    d = np.zeros((6, 6))
    d[:3, :3] = lam
    d[[0, 1, 2], [0, 1, 2]] += 2.0 * mu
    d[[3, 4, 5], [3, 4, 5]] = mu
    return d


def plane_strain_elasticity(E: float, nu: float) -> np.ndarray:
    """Plane-strain elasticity (3, 3) [Pa] on (xx, yy, xy)."""
    return isotropic_elasticity(E, nu)[np.ix_(VOIGT_2D, VOIGT_2D)]


def elasticity(E: float, nu: float, dim: int) -> np.ndarray:
    """The element's elasticity matrix: plane strain (3, 3) in 2D, (6, 6) in 3D."""
    return plane_strain_elasticity(E, nu) if dim == 2 else isotropic_elasticity(E, nu)


def isotropic_compliance(E: float, nu: float) -> np.ndarray:
    """Compliance matrix (6, 6) [1/Pa]: eps = S sigma, engineering shear strains (the inverse of
    :func:`isotropic_elasticity`)."""
    s = np.zeros((6, 6))
    s[:3, :3] = -nu / E
    s[[0, 1, 2], [0, 1, 2]] = 1.0 / E
    s[[3, 4, 5], [3, 4, 5]] = 2.0 * (1.0 + nu) / E
    return s


def strain_energy(sigma: np.ndarray, wdet: np.ndarray, E: float, nu: float) -> float:
    """sum over points of w sigma . S sigma / 2 [J] (per unit thickness in plane strain) for Voigt
    stresses (..., 6) and weights (...)."""
    eps = sigma @ isotropic_compliance(E, nu)  # S is symmetric
    return float(0.5 * np.sum(np.sum(eps * sigma, axis=-1) * wdet))
