"""Loss of ellipticity of the acoustic tensor (paper eq. 7-8) and its closed forms for Drucker-Prager.

``A_ik(n) = n_j C_ijkl n_l``; in the Voigt convention of :mod:`rockfrac.laws.drucker_prager_params`
(C maps strain-like to stress-like) ``A = N(n)^T C N(n)`` with ``N(n) a`` the strain-like Voigt
vector of ``sym(a x n)``. The indicator is ``det A(n) / det A^e(n)`` (1 for an elastic tangent);
localization when its minimum over unit normals is ``<= 0``. ``A(n) = A(-n)``, so plane-strain
normals ``n = (cos t, sin t, 0)`` sweep ``t in [0, pi)``; the 3D search sweeps a (polar, azimuth) grid
of the whole sphere (no special case at the hemisphere's rim) and merges ``n`` with ``-n``.

Angles: the *normal angle* is that of ``n`` from the x axis (in the x-y plane), in ``[0, 180)``
degrees; the *band angle* (the crack trace from horizontal) is the normal angle minus 90 degrees,
normalized to ``(-90, 90]``. The slip direction m is the unit null vector of A (``A m = 0``), signed
so that ``m . n >= 0`` (opening for a dilatant band).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rockfrac.laws import drucker_prager as dp
from rockfrac.laws.acoustic import (
    _acoustic,  # noqa: F401  (re-exported: tests reach the kernels as bifurcation.<name>)
    _acoustic_dense,  # noqa: F401  (re-exported, as above)
    _cofactor,  # noqa: F401  (re-exported, as above)
    _ratio,
    acoustic_tensor,
    det_ratios,  # noqa: F401  (re-exported, as above)
)
from rockfrac.laws.bifurcation_plane import (
    MAX_MINIMA,
    _plane_strain_minima,
    minima_plane_strain,
    screen_plane_strain,  # noqa: F401  (re-exported, as above)
)
from rockfrac.laws.bifurcation_sphere import _refine_sphere, _sphere_candidates
from rockfrac.laws.drucker_prager_params import DruckerPrager

N_SWEEP = 360  # plane-strain sweep points over [0, pi)
N_POLAR = 60  # 3D sweep: polar levels over (0, pi), full sphere
N_AZIMUTH = 120  # 3D sweep: azimuths over [0, 2 pi)


# --------------------------------------------------------------------------------------------
# result object and public searches
# --------------------------------------------------------------------------------------------


def _canonical(n: np.ndarray) -> np.ndarray:
    """Sign of n fixed so that the first nonzero of (n_y, n_x, n_z) is positive."""
    for k in (1, 0, 2):
        if abs(n[k]) > 1.0e-14:
            return n if n[k] > 0.0 else -n
    return n


def _band_angle(n: np.ndarray) -> float:
    """Band angle [rad] from the x axis of the plane of normal n: normal angle - pi/2, in (-pi/2, pi/2]."""
    a = math.atan2(n[1], n[0]) % math.pi - 0.5 * math.pi
    return a + math.pi if a <= -0.5 * math.pi else a


def slip_direction(c: np.ndarray, n: np.ndarray) -> np.ndarray:
    """Unit m with A(n) m ~ 0 (right singular vector of the smallest singular value), m . n >= 0."""
    _, _, vt = np.linalg.svd(acoustic_tensor(np.ascontiguousarray(c, dtype=float), np.asarray(n, float)))
    m = vt[-1]
    d = float(m @ n)
    if d < 0.0 or (d == 0.0 and _canonical(m)[0] != m[0]):
        m = -m
    return m


@dataclass(frozen=True)
class Localization:
    """Local minima of det A(n)/det A^e(n), lowest first: normals (k, 3), ratios (k,), slips (k, 3)."""

    normals: np.ndarray
    ratios: np.ndarray
    slips: np.ndarray

    @property
    def min_ratio(self) -> float:
        """Minimum of det A / det A^e over the normals (<= 0: localized)."""
        return float(self.ratios[0])

    @property
    def localized(self) -> bool:
        return self.min_ratio <= 0.0

    @property
    def normal_angles(self) -> np.ndarray:
        """Angles of the normals' x-y projections from the x axis [rad], in [0, pi)."""
        return np.mod(np.arctan2(self.normals[:, 1], self.normals[:, 0]), math.pi)

    @property
    def band_angles(self) -> np.ndarray:
        """Band (crack trace) angles from the x axis [rad], normal angle - pi/2 in (-pi/2, pi/2]."""
        return np.array([_band_angle(n) for n in self.normals])

    @property
    def normal_angles_deg(self) -> np.ndarray:
        return np.degrees(self.normal_angles)

    @property
    def band_angles_deg(self) -> np.ndarray:
        return np.degrees(self.band_angles)


def _result(c: np.ndarray, normals: list[np.ndarray], ratios: list[float]) -> Localization:
    """Deduplicate (n ~ -n), sort by ratio (ties within 1e-10: band angle descending), add slips."""
    normals = [_canonical(n / np.linalg.norm(n)) for n in normals]
    band = [_band_angle(n) for n in normals]
    order = sorted(range(len(ratios)), key=lambda k: (round(float(ratios[k]), 10), -band[k]))
    keep_n: list[np.ndarray] = []
    keep_r: list[float] = []
    for k in order:
        n = normals[k]
        if any(abs(abs(float(n @ q)) - 1.0) < 1.0e-12 or np.linalg.norm(n - q) < 1e-7 for q in keep_n):
            continue
        keep_n.append(n)
        keep_r.append(float(ratios[k]))
    nn = np.array(keep_n)
    return Localization(nn, np.array(keep_r), np.array([slip_direction(c, n) for n in nn]))


def localization_plane_strain(c: np.ndarray, ce: np.ndarray, n_sweep: int = N_SWEEP) -> Localization:
    """Minima of det A / det A^e over in-plane normals (cos t, sin t, 0): sweep, then bisection.

    c, ce: (6, 6) Voigt tangent and elastic moduli [Pa]. All local minima are returned (the two
    conjugate bands of a plane-strain state), lowest first; angles to ~1e-12 rad.
    """
    c = np.ascontiguousarray(c, dtype=float)
    ce = np.ascontiguousarray(ce, dtype=float)
    th = np.empty(n_sweep)
    rr = np.empty(n_sweep)
    k = _plane_strain_minima(c, ce, n_sweep, th, rr)
    if k == 0:  # flat (e.g. elastic): report theta = 0
        th[0], rr[0], k = 0.0, _ratio(c, ce, np.array([1.0, 0.0, 0.0])), 1
    normals = [np.array([math.cos(t), math.sin(t), 0.0]) for t in th[:k]]
    return _result(c, normals, list(rr[:k]))


def localization_3d(c: np.ndarray, ce: np.ndarray, n_polar: int = N_POLAR, n_azimuth: int = N_AZIMUTH,
                    max_candidates: int = 16) -> Localization:
    """Minima of det A / det A^e over unit normals: sphere sweep, then Newton refinement of each."""
    c = np.ascontiguousarray(c, dtype=float)
    ce = np.ascontiguousarray(ce, dtype=float)
    cand = np.empty((max_candidates, 3))
    k = _sphere_candidates(c, ce, n_polar, n_azimuth, cand)
    normals = [_refine_sphere(c, ce, n) for n in cand[:k]]
    ratios = [float(_ratio(c, ce, n)) for n in normals]
    return _result(c, normals, ratios)


# --------------------------------------------------------------------------------------------
# Drucker-Prager: eq. (8) at a stress, and the closed forms used as test oracles
# --------------------------------------------------------------------------------------------


def perfectly_plastic_tangent_at(law: DruckerPrager, sigma: np.ndarray) -> np.ndarray:
    """Eq. (8) c_ep (6, 6) [Pa] with f, g of the Drucker-Prager law at the stress sigma (6,) [Pa]."""
    p = law.as_array()
    sigma = np.ascontiguousarray(sigma, dtype=float)
    return dp.perfectly_plastic_tangent(law.elastic_matrix(), dp.yield_gradient(sigma, p),
                                        dp.potential_gradient(sigma, p))


def localization_at(law: DruckerPrager, sigma: np.ndarray, plane_strain: bool = True) -> Localization:
    """Localization analysis of eq. (7)-(8) at the stress sigma (6,) [Pa] (on the cone, s != 0)."""
    c = perfectly_plastic_tangent_at(law, sigma)
    ce = law.elastic_matrix()
    return localization_plane_strain(c, ce) if plane_strain else localization_3d(c, ce)


def _tensor(sigma: np.ndarray) -> np.ndarray:
    s = np.asarray(sigma, dtype=float)
    return np.array([[s[0], s[3], s[5]], [s[3], s[1], s[4]], [s[5], s[4], s[2]]])


def runesson_angle(sigma: np.ndarray, beta: float, b: float, nu: float) -> float:
    """Plane-strain critical angle theta0 [rad] of Runesson, Ottosen & Peric (1991) for DP.

    Angle between the band normal and the most compressive in-plane principal direction;
    sigma (6,) [Pa] with sigma_yz = sigma_xz = 0. With the in-plane deviatoric principal stresses
    s1 >= s2, s3 = s_zz and a = sqrt(2)(beta + b)/3: c1 = s2 + nu s3 + (1 + nu) a |s| / 2,
    c2 = s1 + nu s3 + (1 + nu) a |s| / 2, tan^2 theta0 = -c2/c1 if c1 < 0 < c2; otherwise the
    critical normal is a principal direction (0 if c2 <= 0, pi/2 if c1 >= 0).
    """
    s = np.asarray(sigma, dtype=float)
    pm = (s[0] + s[1] + s[2]) / 3.0
    sd = np.array([s[0] - pm, s[1] - pm, s[2] - pm, s[3], s[4], s[5]])
    sn = math.sqrt(sd[0] ** 2 + sd[1] ** 2 + sd[2] ** 2 + 2.0 * (sd[3] ** 2 + sd[4] ** 2 + sd[5] ** 2))
    w = np.linalg.eigvalsh(np.array([[sd[0], sd[3]], [sd[3], sd[1]]]))
    s2, s1, s3 = w[0], w[1], sd[2]
    a = math.sqrt(2.0) * (beta + b) / 3.0
    c1 = s2 + nu * s3 + 0.5 * (1.0 + nu) * a * sn
    c2 = s1 + nu * s3 + 0.5 * (1.0 + nu) * a * sn
    if c1 < 0.0 < c2:
        return math.atan(math.sqrt(-c2 / c1))
    return 0.0 if c2 <= 0.0 else 0.5 * math.pi


def runesson_normals(sigma: np.ndarray, beta: float, b: float, nu: float) -> np.ndarray:
    """The two conjugate plane-strain normals (2, 3) at +-theta0 from the most compressive direction."""
    s = np.asarray(sigma, dtype=float)
    w, v = np.linalg.eigh(np.array([[s[0], s[3]], [s[3], s[1]]]))
    d = v[:, 0]  # most compressive in-plane direction
    t0 = runesson_angle(s, beta, b, nu)
    out = []
    for sg in (1.0, -1.0):
        ct, st = math.cos(sg * t0), math.sin(sg * t0)
        out.append(_canonical(np.array([ct * d[0] - st * d[1], st * d[0] + ct * d[1], 0.0])))
    return np.array(out)


def rudnicki_rice_angle(sigma: np.ndarray, beta: float, b: float, nu: float) -> float:
    """3D critical angle theta0 = pi/4 + asin(alpha)/2 [rad] of Rudnicki & Rice (1975) for DP.

    Angle between the band normal and the most compressive principal axis; the normal lies in the
    plane of the most and least compressive axes. alpha = [(2/3)(1 + nu)(beta + b) - N (1 - 2 nu)]
    / sqrt(4 - 3 N^2), N = s_II / sqrt(J2) (s_II the intermediate deviatoric principal stress);
    |alpha| > 1 is clipped (the normal is then a principal direction).
    """
    w = np.linalg.eigvalsh(_tensor(sigma))
    sd = w - w.mean()
    j2 = 0.5 * float(sd @ sd)
    nn = sd[1] / math.sqrt(j2)
    alpha = ((2.0 / 3.0) * (1.0 + nu) * (beta + b) - nn * (1.0 - 2.0 * nu)) / math.sqrt(4.0 - 3.0 * nn**2)
    return 0.25 * math.pi + 0.5 * math.asin(min(1.0, max(-1.0, alpha)))


def peak_cohesion(sigma: np.ndarray, n: np.ndarray, tan_phi: float) -> float:
    """Eq. (28) for a homogeneous stress: c_p = |T_t| + T_n* tan(phi) [Pa] on the plane of normal n.

    T = sigma n, T_n = n . T, |T_t| = |T - T_n n|, T_n* = min(T_n, 0).
    """
    n = np.asarray(n, dtype=float) / np.linalg.norm(n)
    t = _tensor(sigma) @ n
    tn = float(t @ n)
    return float(np.linalg.norm(t - tn * n)) + min(tn, 0.0) * tan_phi


def min_ratios_plane_strain(law: DruckerPrager, sigma: np.ndarray, n_sweep: int = N_SWEEP) -> np.ndarray:
    """``localization_at(law, s).min_ratio`` for every row s of sigma (n, 6) [Pa], in one compiled pass.

    The ordering of :func:`_result` (ratio rounded to 1e-10, then band angle descending) picks which
    minimum is reported; it is applied here to all points at once.
    """
    sigma = np.ascontiguousarray(sigma, dtype=float)
    n = sigma.shape[0]
    th = np.zeros((n, MAX_MINIMA))
    rr = np.full((n, MAX_MINIMA), np.inf)
    count = np.zeros(n, dtype=np.int64)
    minima_plane_strain(sigma, law.as_array(), law.elastic_matrix(), n_sweep, th, rr, count)
    valid = np.arange(MAX_MINIMA)[None, :] < np.minimum(count, MAX_MINIMA)[:, None]
    pt, j = np.nonzero(valid)
    t = th[pt, j]
    nrm = np.stack([np.cos(t), np.sin(t), np.zeros_like(t)], axis=1)
    nrm /= np.sqrt((nrm * nrm).sum(axis=1))[:, None]
    flip = np.where(np.abs(nrm[:, 1]) > 1e-14, nrm[:, 1] < 0.0, nrm[:, 0] < 0.0)
    nrm[flip] *= -1.0
    band = np.mod(np.arctan2(nrm[:, 1], nrm[:, 0]), math.pi) - 0.5 * math.pi
    band = np.where(band <= -0.5 * math.pi, band + math.pi, band)
    rounded = np.array([round(x, 10) for x in rr[pt, j].tolist()])
    order = np.lexsort((j, -band, rounded, pt))  # per point: _result's sort key, stable
    first = order[np.concatenate(([True], pt[order][1:] != pt[order][:-1]))]
    out = np.empty(n)
    out[pt[first]] = rr[pt[first], j[first]]
    for i in np.flatnonzero(count > MAX_MINIMA):  # many minima (never seen): the one-point path
        out[i] = localization_at(law, sigma[i]).min_ratio
    return out
