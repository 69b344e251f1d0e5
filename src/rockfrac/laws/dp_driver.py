"""Material-point driver of the Drucker-Prager law for the paper's homogeneous specimen (Sect. 7).

Plane strain (``eps_zz = 0``), no shear. Stage 1 applies the lateral confinement
``sigma_xx = -p`` with ``eps_yy = 0`` (the top is held while the sides are loaded, as in the FE
case); stage 2 prescribes the axial strain ``eps_yy`` (negative: compression) while
``sigma_xx = -p`` is held. Each step solves ``sigma_xx(eps_xx) + p = 0`` by Newton with the
consistent tangent ``d sigma_xx / d eps_xx``. At every converged plastic step the bifurcation
indicator ``min_n det A / det A^e`` of eq. (7)-(8) (elastic-perfectly-plastic tangent with f, g at
the current stress, in-plane normals) is evaluated; the first step where it is ``<= 0`` is
located within the step by bisection on the step fraction. Axial force per unit thickness
``F = -sigma_yy W`` [N/m] (compression positive).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rockfrac.laws import drucker_prager as dp
from rockfrac.laws.bifurcation import Localization, localization_at
from rockfrac.laws.drucker_prager_params import (
    MODE_CONE,
    MODE_ELASTIC,
    N_STATE,
    S_GAMMA,
    S_MODE,
    DruckerPrager,
)

MAX_ITER = 30  # Newton iterations per step
TOL = 1.0e-12  # |sigma_xx + p| <= TOL * (p + |sigma|)
LOCATE_ITER = 60  # bisection steps on the step fraction


@dataclass(frozen=True)
class Onset:
    """Bifurcation onset located within a step: the stress where det A / det A^e crosses 0."""

    step: int  # first converged step (index into the path arrays) with det ratio <= 0
    fraction: float  # onset at eps_yy = eps_yy[step - 1] + fraction * (eps_yy[step] - eps_yy[step - 1])
    eps_xx: float
    eps_yy: float
    sigma: np.ndarray  # (6,) [Pa] at the located onset
    gamma: float
    force: float  # -sigma_yy W [N/m]
    localization: Localization  # at the located onset (ratio ~ 0)


@dataclass
class SpecimenPath:
    """Converged steps (confinement then axial), arrays of length n_steps + 1 (row 0: virgin)."""

    stage: np.ndarray  # 0 start, 1 confinement, 2 axial
    eps_xx: np.ndarray
    eps_yy: np.ndarray
    sigma: np.ndarray  # (n, 6) [Pa]
    gamma: np.ndarray
    mode: np.ndarray  # 0 elastic, 1 cone, 2 apex
    det_ratio: np.ndarray  # min_n det A / det A^e of eq. (8) (1 when elastic, nan at the apex)
    band_angles: np.ndarray  # (n, 2) band angles [deg] of the two lowest minima (nan when elastic)
    iterations: np.ndarray
    width: float
    onset: Onset | None = None
    first_yield: int | None = None  # first plastic row

    @property
    def step(self) -> np.ndarray:
        return np.arange(self.eps_yy.shape[0])

    @property
    def force(self) -> np.ndarray:
        """Axial force -sigma_yy W [N/m], compression positive."""
        return -self.sigma[:, 1] * self.width

    def columns(self) -> dict[str, np.ndarray]:
        """The path as named columns (CSV-ready)."""
        return {"step": self.step, "stage": self.stage, "eps_xx": self.eps_xx, "eps_yy": self.eps_yy,
                "sigma_xx": self.sigma[:, 0], "sigma_yy": self.sigma[:, 1], "sigma_zz": self.sigma[:, 2],
                "gamma": self.gamma, "mode": self.mode, "det_ratio": self.det_ratio,
                "band_angle_1": self.band_angles[:, 0], "band_angle_2": self.band_angles[:, 1],
                "force": self.force, "iterations": self.iterations}


class DriverError(RuntimeError):
    """The lateral equilibrium did not converge or the return map failed."""


def _solve_step(eps_yy: float, sxx_target: float, exx0: float, s_old: np.ndarray, p: np.ndarray):
    """Newton on eps_xx for sigma_xx = sxx_target at eps_yy; returns (eps_xx, sigma, C, state, its)."""
    eps = np.zeros(6)
    sig = np.empty(6)
    c = np.empty((6, 6))
    s_new = np.empty(N_STATE)
    exx = exx0
    for it in range(MAX_ITER + 1):
        eps[0], eps[1] = exx, eps_yy
        st = dp.return_map(eps, s_old, p, sig, c, s_new)
        if st < 0:
            raise DriverError(f"return map failed (status {st}) at eps_xx = {exx:.6e}, "
                              f"eps_yy = {eps_yy:.6e}")
        r = sig[0] - sxx_target
        if abs(r) <= TOL * (abs(sxx_target) + math.sqrt(float(sig @ sig)) + 1.0):
            return exx, sig.copy(), c.copy(), s_new.copy(), it
        exx -= r / c[0, 0]
    raise DriverError(f"lateral equilibrium not converged in {MAX_ITER} iterations at "
                      f"eps_yy = {eps_yy:.6e}")


def _indicator(law: DruckerPrager, sigma: np.ndarray, mode: float) -> tuple[float, Localization | None]:
    if mode == MODE_ELASTIC:
        return 1.0, None
    if mode != MODE_CONE:
        return math.nan, None
    loc = localization_at(law, sigma)
    return loc.min_ratio, loc


def drive_specimen(law: DruckerPrager, *, confinement: float = 2.0e4, axial_strain: float = -5.0e-3,
                   steps: int = 500, confinement_steps: int = 1, width: float = 0.04,
                   locate: bool = True, stop_at_onset: bool = False) -> SpecimenPath:
    """Drive the homogeneous plane-strain specimen (module doc); axial_strain < 0 compresses.

    stop_at_onset: end the path at the first step with det A / det A^e <= 0.
    """
    p = law.as_array()
    targets = [(0.0, -confinement * (k + 1) / confinement_steps, 1) for k in range(confinement_steps)]
    targets += [(axial_strain * (k + 1) / steps, -confinement, 2) for k in range(steps)]
    n = len(targets) + 1
    out = SpecimenPath(stage=np.zeros(n, dtype=int), eps_xx=np.zeros(n), eps_yy=np.zeros(n),
                       sigma=np.zeros((n, 6)), gamma=np.zeros(n), mode=np.zeros(n),
                       det_ratio=np.ones(n), band_angles=np.full((n, 2), np.nan),
                       iterations=np.zeros(n, dtype=int), width=width)
    states = np.zeros((n, N_STATE))
    c_prev = law.elastic_matrix()
    last = n - 1
    for k, (eyy, sxx, stage) in enumerate(targets, start=1):
        guess = out.eps_xx[k - 1] - (c_prev[0, 1] * (eyy - out.eps_yy[k - 1])
                                     + (out.sigma[k - 1, 0] - sxx)) / c_prev[0, 0]
        exx, sig, c, s_new, its = _solve_step(eyy, sxx, guess, states[k - 1], p)
        states[k] = s_new
        out.stage[k], out.eps_xx[k], out.eps_yy[k], out.sigma[k] = stage, exx, eyy, sig
        out.gamma[k], out.mode[k], out.iterations[k] = s_new[S_GAMMA], s_new[S_MODE], its
        ratio, loc = _indicator(law, sig, s_new[S_MODE])
        out.det_ratio[k] = ratio
        if loc is not None:
            ang = loc.band_angles_deg
            out.band_angles[k, : min(2, ang.size)] = ang[:2]
        if out.first_yield is None and s_new[S_MODE] != MODE_ELASTIC:
            out.first_yield = k
        c_prev = c
        if out.onset is None and ratio <= 0.0:
            out.onset = _locate(law, p, out, states, k, sxx) if locate else _at_step(law, out, k)
            if stop_at_onset:
                last = k
                break
    if last < n - 1:
        for name in ("stage", "eps_xx", "eps_yy", "sigma", "gamma", "mode", "det_ratio", "band_angles",
                     "iterations"):
            setattr(out, name, getattr(out, name)[: last + 1])
    return out


def _at_step(law: DruckerPrager, out: SpecimenPath, k: int) -> Onset:
    loc = localization_at(law, out.sigma[k])
    return Onset(k, 1.0, out.eps_xx[k], out.eps_yy[k], out.sigma[k].copy(), out.gamma[k],
                 -out.sigma[k, 1] * out.width, loc)


def _locate(law: DruckerPrager, p: np.ndarray, out: SpecimenPath, states: np.ndarray, k: int,
            sxx: float) -> Onset:
    """Bisection on the fraction a of step k (from the state of step k - 1) where the ratio hits 0."""
    e0, e1 = out.eps_yy[k - 1], out.eps_yy[k]
    x0, x1 = out.eps_xx[k - 1], out.eps_xx[k]
    lo, hi = 0.0, 1.0
    if out.det_ratio[k - 1] <= 0.0:
        return _at_step(law, out, k)
    best = None
    for _ in range(LOCATE_ITER):
        a = 0.5 * (lo + hi)
        exx, sig, _, s_new, _ = _solve_step(e0 + a * (e1 - e0), sxx, x0 + a * (x1 - x0), states[k - 1], p)
        ratio, loc = _indicator(law, sig, s_new[S_MODE])
        if ratio <= 0.0:
            hi = a
            best = (a, exx, sig, s_new, loc)
        else:
            lo = a
        if hi - lo < 1.0e-14:
            break
    if best is None:
        return _at_step(law, out, k)
    a, exx, sig, s_new, loc = best
    assert loc is not None  # an indicator at or below zero comes with its localization
    return Onset(k, a, exx, e0 + a * (e1 - e0), sig, s_new[S_GAMMA], -sig[1] * out.width, loc)


def elastic_stress(law: DruckerPrager, confinement: float, eps_yy: float) -> np.ndarray:
    """Closed-form elastic stress (6,) [Pa] of the specimen after confinement at axial strain eps_yy.

    sigma_xx = -p, sigma_yy = -p nu/(1 - nu) + E eps_yy / (1 - nu^2), sigma_zz = nu (sigma_xx + sigma_yy).
    """
    nu = law.nu
    syy = -confinement * nu / (1.0 - nu) + law.E * eps_yy / (1.0 - nu * nu)
    return np.array([-confinement, syy, nu * (syy - confinement), 0.0, 0.0, 0.0])


def elastic_yield_force(law: DruckerPrager, confinement: float = 2.0e4, width: float = 0.04) -> float:
    """Axial force -sigma_yy W [N/m] at first yield on the elastic path (F = 0 of the initial surface)."""
    from scipy.optimize import brentq

    p = law.as_array()

    def f(e):
        return dp.yield_value(elastic_stress(law, confinement, e), 0.0, p)

    if f(0.0) > 0.0:
        raise DriverError("the confinement alone yields the material")
    hi = -1.0e-6
    while f(hi) < 0.0:
        hi *= 2.0
        if hi < -1.0:
            raise DriverError("no yield on the elastic path (eps_yy down to -1)")
    e_y = brentq(f, hi, 0.0, xtol=1e-16, rtol=1e-15)
    return -elastic_stress(law, confinement, e_y)[1] * width
