"""Parameter and state layouts of the nonassociative Drucker-Prager law (paper Sect. 3.1, ref [7]).

Kernels are Numba functions on flat float64 arrays; these integer constants name the slots.
Stresses in Pa, tension positive, ``p = tr(sigma)/3``, ``s = dev(sigma)``, ``|s| = sqrt(s:s)``.

Voigt convention for every 3D quantity, order ``(xx, yy, zz, xy, yz, xz)``:

* stress-like vectors (sigma, s, Ce:g) hold the tensor components;
* strain-like vectors (eps, eps^p, f = dF/dsigma, g = dG/dsigma) hold engineering shears
  (``gamma_xy = 2 eps_xy``), so ``sigma:eps = sigma_v . eps_v`` and ``f_v = dF/d(sigma_v)``;
* a 6 x 6 modulus maps strain-like to stress-like (``sigma_v = C_v eps_v``).

Plane strain is ``eps_zz = eps_yz = eps_xz = 0`` in the same 6-vectors.

The law (one routine for Hex8 and plane-strain Q4):

* ``F = sqrt(3/2)|s| + sqrt(3) (beta p - kappa)``, ``kappa = kappa0 + H gamma``;
* ``G = sqrt(3/2)|s| + sqrt(3) b p``; ``eps^p' = gamma' dG/dsigma`` (subgradient at the apex);
* ``gamma`` is the accumulated plastic multiplier; on the cone it equals the equivalent plastic
  shear strain ``sqrt(2/3)|e^p|``. ``H > 0`` hardens, ``H < 0`` softens.

Note: EDE_NOTES writes ``- H gamma`` outside the ``sqrt(3)``; here ``H`` multiplies ``gamma`` inside
it, so the notes' ``H`` is ``sqrt(3)`` times this one (``X_H = 3(mu + beta b K) + sqrt(3) H``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

# --- parameter vector slots -------------------------------------------------------------
P_E = 0  # Young's modulus E [Pa]
P_NU = 1  # Poisson's ratio nu [-]
P_BETA = 2  # friction coefficient beta of F [-]
P_B = 3  # dilatancy coefficient b of G [-]
P_KAPPA0 = 4  # initial cohesion-like strength kappa0 [Pa]
P_H = 5  # hardening modulus H [Pa] (kappa = kappa0 + H gamma; H < 0 softens)
N_PARAMS = 6

# --- state vector slots (per integration point) ------------------------------------------
S_EPS_P = 0  # plastic strain, slots 0..5, Voigt (xx, yy, zz, xy, yz, xz), engineering shear
S_GAMMA = 6  # accumulated plastic multiplier gamma [-]
S_DGAMMA = 7  # Delta gamma of the last update [-]
S_MODE = 8  # MODE_ELASTIC / MODE_CONE / MODE_APEX of the last update
N_STATE = 9

MODE_ELASTIC = 0.0
MODE_CONE = 1.0
MODE_APEX = 2.0

VOIGT = ("xx", "yy", "zz", "xy", "yz", "xz")


def mohr_coulomb_beta(phi: float) -> float:
    """Plane-strain Mohr-Coulomb match: beta = 3 tan(phi) / sqrt(9 + 12 tan^2 phi) (phi in rad)."""
    t = math.tan(phi)
    return 3.0 * t / math.sqrt(9.0 + 12.0 * t * t)


def mohr_coulomb_kappa(phi: float, c: float) -> float:
    """Plane-strain Mohr-Coulomb match: kappa = 3 c / sqrt(9 + 12 tan^2 phi) [Pa]."""
    t = math.tan(phi)
    return 3.0 * c / math.sqrt(9.0 + 12.0 * t * t)


def mohr_coulomb_angle(beta: float) -> float:
    """Inverse of :func:`mohr_coulomb_beta`: phi [rad] with tan(phi) = 3 beta / sqrt(9 - 12 beta^2)."""
    if not 0.0 <= beta < math.sqrt(3.0) / 2.0:
        raise ValueError(f"beta = {beta!r}: a plane-strain Mohr-Coulomb match needs "
                         "0 <= beta < sqrt(3)/2")
    return math.atan(3.0 * beta / math.sqrt(9.0 - 12.0 * beta * beta))


def mohr_coulomb_cohesion(beta: float, kappa: float) -> float:
    """Inverse of :func:`mohr_coulomb_kappa`: c [Pa] of the plane-strain match."""
    t = math.tan(mohr_coulomb_angle(beta))
    return kappa * math.sqrt(9.0 + 12.0 * t * t) / 3.0


@dataclass(frozen=True)
class DruckerPrager:
    """Drucker-Prager parameters: E, kappa0, H [Pa]; nu, beta, b [-] (see the module doc)."""

    E: float
    nu: float
    beta: float
    b: float
    kappa0: float
    H: float = 0.0

    def __post_init__(self) -> None:
        problems = []
        for name in ("E", "nu", "beta", "b", "kappa0", "H"):
            if not math.isfinite(getattr(self, name)):
                problems.append(f"{name} must be a finite number (got {getattr(self, name)!r})")
        if problems:
            raise ValueError("; ".join(problems))
        if not self.E > 0.0:
            problems.append(f"E must be > 0 (got {self.E!r})")
        if not -1.0 < self.nu < 0.5:
            problems.append(f"nu must be in (-1, 0.5) (got {self.nu!r})")
        if self.beta < 0.0:
            problems.append(f"beta must be >= 0 (got {self.beta!r})")
        if self.b < 0.0:
            problems.append(f"b must be >= 0 (got {self.b!r})")
        if self.kappa0 < 0.0:
            problems.append(f"kappa0 must be >= 0 (got {self.kappa0!r})")
        if not problems and not self.cone_modulus > 0.0:
            problems.append(f"H = {self.H!r} softens too fast: 3 (mu + beta b K) + sqrt(3) H must be > 0 "
                            f"(H > {-math.sqrt(3.0) * (self.mu + self.beta * self.b * self.K):.6g} Pa)")
        if problems:
            raise ValueError("; ".join(problems))

    @classmethod
    def from_mohr_coulomb(cls, E: float, nu: float, phi: float, c: float, psi: float,
                          H: float = 0.0) -> DruckerPrager:
        """Plane-strain Mohr-Coulomb match (angles phi, psi in rad, cohesion c in Pa)."""
        for name, ang in (("phi", phi), ("psi", psi)):
            if not 0.0 <= ang < math.pi / 2:
                raise ValueError(f"{name} must be in [0, pi/2) rad (got {ang!r})")
        return cls(E=E, nu=nu, beta=mohr_coulomb_beta(phi), b=mohr_coulomb_beta(psi),
                   kappa0=mohr_coulomb_kappa(phi, c), H=H)

    @property
    def K(self) -> float:
        """Bulk modulus [Pa]."""
        return self.E / (3.0 * (1.0 - 2.0 * self.nu))

    @property
    def mu(self) -> float:
        """Shear modulus [Pa]."""
        return self.E / (2.0 * (1.0 + self.nu))

    @property
    def cone_modulus(self) -> float:
        """X_H = f:Ce:g + sqrt(3) H = 3 (mu + beta b K) + sqrt(3) H [Pa], the cone-return denominator."""
        return 3.0 * (self.mu + self.beta * self.b * self.K) + math.sqrt(3.0) * self.H

    @property
    def friction_angle(self) -> float:
        """phi [rad] of the plane-strain Mohr-Coulomb match of beta."""
        return mohr_coulomb_angle(self.beta)

    @property
    def dilatancy_angle(self) -> float:
        """psi [rad] of the plane-strain Mohr-Coulomb match of b."""
        return mohr_coulomb_angle(self.b)

    def elastic_matrix(self) -> np.ndarray:
        """Isotropic Ce (6, 6) [Pa] in the Voigt convention of the module (strain-like -> stress-like)."""
        lam = self.K - 2.0 * self.mu / 3.0
        c = np.zeros((6, 6))
        c[:3, :3] = lam
        c[np.arange(3), np.arange(3)] += 2.0 * self.mu
        c[np.arange(3, 6), np.arange(3, 6)] = self.mu
        return c

    def as_array(self) -> np.ndarray:
        p = np.zeros(N_PARAMS)
        p[P_E] = self.E
        p[P_NU] = self.nu
        p[P_BETA] = self.beta
        p[P_B] = self.b
        p[P_KAPPA0] = self.kappa0
        p[P_H] = self.H
        return p


def initial_state(n_points: int) -> np.ndarray:
    """Virgin state for ``n_points`` integration points, shape (n_points, N_STATE)."""
    return np.zeros((n_points, N_STATE))
