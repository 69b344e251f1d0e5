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

import numba as nb
import numpy as np

from rockfrac.laws import drucker_prager as dp
from rockfrac.laws.drucker_prager_params import DruckerPrager

N_SWEEP = 360  # plane-strain sweep points over [0, pi)
N_POLAR = 60  # 3D sweep: polar levels over (0, pi), full sphere
N_AZIMUTH = 120  # 3D sweep: azimuths over [0, 2 pi)


# --------------------------------------------------------------------------------------------
# acoustic tensor, its determinant and gradients (Numba)
# --------------------------------------------------------------------------------------------


@nb.njit(cache=True, inline="always")
def _cn_row(c, a, n0, n1, n2):
    """Row a of C N(n) (3 values): N(n)'s three nonzeros per column, in the order of the full sum."""
    return (c[a, 0] * n0 + c[a, 3] * n1 + c[a, 5] * n2,
            c[a, 1] * n1 + c[a, 3] * n0 + c[a, 4] * n2,
            c[a, 2] * n2 + c[a, 4] * n1 + c[a, 5] * n0)


@nb.njit(cache=True)
def _acoustic(c, n, out):
    """out (3, 3) = N(n)^T c N(n): A_ik = n_j C_ijkl n_l for c (6, 6) Voigt.

    N(n) (6, 3), strain-like sym(a x n) = N(n) a, has rows (n0,0,0), (0,n1,0), (0,0,n2), (n1,n0,0),
    (0,n2,n1), (n2,0,n0); its zeros are skipped (no work arrays) and the nonzero products summed in
    the order of the full products, so the values are those of the dense form.
    """
    a = _acoustic9(c, n[0], n[1], n[2])
    out[0, 0], out[0, 1], out[0, 2] = a[0], a[1], a[2]
    out[1, 0], out[1, 1], out[1, 2] = a[3], a[4], a[5]
    out[2, 0], out[2, 1], out[2, 2] = a[6], a[7], a[8]


@nb.njit(cache=True)
def _acoustic_dense(c, n, out):
    """The dense form of :func:`_acoustic` (reference of the tests)."""
    nm = np.zeros((6, 3))  # strain-like sym(a x n) = nm @ a
    nm[0, 0] = n[0]
    nm[1, 1] = n[1]
    nm[2, 2] = n[2]
    nm[3, 0], nm[3, 1] = n[1], n[0]
    nm[4, 1], nm[4, 2] = n[2], n[1]
    nm[5, 0], nm[5, 2] = n[2], n[0]
    cn = np.zeros((6, 3))
    for a in range(6):
        for k in range(3):
            acc = 0.0
            for b in range(6):
                acc += c[a, b] * nm[b, k]
            cn[a, k] = acc
    for i in range(3):
        for k in range(3):
            acc = 0.0
            for a in range(6):
                acc += nm[a, i] * cn[a, k]
            out[i, k] = acc


@nb.njit(cache=True)
def acoustic_tensor(c, n):
    """Acoustic tensor A(n) (3, 3) [Pa] of the Voigt modulus c (6, 6) for the normal n (3,)."""
    out = np.empty((3, 3))
    _acoustic(c, n, out)
    return out


@nb.njit(cache=True)
def _cofactor(a, cof):
    """cof (3, 3) = d det(a) / d a_ik; returns det(a)."""
    cof[0, 0] = a[1, 1] * a[2, 2] - a[1, 2] * a[2, 1]
    cof[0, 1] = a[1, 2] * a[2, 0] - a[1, 0] * a[2, 2]
    cof[0, 2] = a[1, 0] * a[2, 1] - a[1, 1] * a[2, 0]
    cof[1, 0] = a[0, 2] * a[2, 1] - a[0, 1] * a[2, 2]
    cof[1, 1] = a[0, 0] * a[2, 2] - a[0, 2] * a[2, 0]
    cof[1, 2] = a[0, 1] * a[2, 0] - a[0, 0] * a[2, 1]
    cof[2, 0] = a[0, 1] * a[1, 2] - a[0, 2] * a[1, 1]
    cof[2, 1] = a[0, 2] * a[1, 0] - a[0, 0] * a[1, 2]
    cof[2, 2] = a[0, 0] * a[1, 1] - a[0, 1] * a[1, 0]
    return a[0, 0] * cof[0, 0] + a[0, 1] * cof[0, 1] + a[0, 2] * cof[0, 2]


@nb.njit(cache=True, inline="always")
def _acoustic9(c, n0, n1, n2):
    """A(n) of :func:`_acoustic` as 9 values, row by row (no arrays)."""
    r0 = _cn_row(c, 0, n0, n1, n2)
    r1 = _cn_row(c, 1, n0, n1, n2)
    r2 = _cn_row(c, 2, n0, n1, n2)
    r3 = _cn_row(c, 3, n0, n1, n2)
    r4 = _cn_row(c, 4, n0, n1, n2)
    r5 = _cn_row(c, 5, n0, n1, n2)
    return (n0 * r0[0] + n1 * r3[0] + n2 * r5[0], n0 * r0[1] + n1 * r3[1] + n2 * r5[1],
            n0 * r0[2] + n1 * r3[2] + n2 * r5[2],
            n1 * r1[0] + n0 * r3[0] + n2 * r4[0], n1 * r1[1] + n0 * r3[1] + n2 * r4[1],
            n1 * r1[2] + n0 * r3[2] + n2 * r4[2],
            n2 * r2[0] + n1 * r4[0] + n0 * r5[0], n2 * r2[1] + n1 * r4[1] + n0 * r5[1],
            n2 * r2[2] + n1 * r4[2] + n0 * r5[2])


@nb.njit(cache=True, inline="always")
def _cofactor9(a):
    """(det, cofactors row by row) of a 3x3 given as 9 values; :func:`_cofactor`'s formulas."""
    a00, a01, a02, a10, a11, a12, a20, a21, a22 = a
    c00 = a11 * a22 - a12 * a21
    c01 = a12 * a20 - a10 * a22
    c02 = a10 * a21 - a11 * a20
    c10 = a02 * a21 - a01 * a22
    c11 = a00 * a22 - a02 * a20
    c12 = a01 * a20 - a00 * a21
    c20 = a01 * a12 - a02 * a11
    c21 = a02 * a10 - a00 * a12
    c22 = a00 * a11 - a01 * a10
    return a00 * c00 + a01 * c01 + a02 * c02, (c00, c01, c02, c10, c11, c12, c20, c21, c22)


@nb.njit(cache=True, inline="always")
def _det_grad3(c, n0, n1, n2):
    """(det A(n), d det A / d n) of :func:`_det_grad` as scalars (no arrays, the same arithmetic)."""
    det, cof = _cofactor9(_acoustic9(c, n0, n1, n2))
    out0 = 0.0
    out1 = 0.0
    out2 = 0.0
    for m in range(3):
        ep = _acoustic9(c, n0 + (1.0 if m == 0 else 0.0), n1 + (1.0 if m == 1 else 0.0),
                        n2 + (1.0 if m == 2 else 0.0))
        em = _acoustic9(c, n0 - (1.0 if m == 0 else 0.0), n1 - (1.0 if m == 1 else 0.0),
                        n2 - (1.0 if m == 2 else 0.0))
        acc = 0.0
        for ik in range(9):
            acc += cof[ik] * 0.5 * (ep[ik] - em[ik])
        if m == 0:
            out0 = acc
        elif m == 1:
            out1 = acc
        else:
            out2 = acc
    g = (out0, out1, out2)
    return det, g


@nb.njit(cache=True)
def _det_grad(c, n, grad):
    """det A(n) and grad (3,) = d det A / d n (n not normalized: A is quadratic in n).

    dA_ik/dn_m = C_imkl n_l + n_j C_ijkm, i.e. N(e_m)^T c N(n) + N(n)^T c N(e_m); computed from
    A(n + e_m) - A(n - e_m) = 2 dA/dn_m (exact: A is quadratic in n).
    """
    det, g = _det_grad3(c, n[0], n[1], n[2])
    for m in range(3):
        grad[m] = g[m]
    return det


@nb.njit(cache=True, inline="always")
def _ratio_grad3(c, ce, n0, n1, n2):
    """(r, dr/dn as 3 values) of :func:`_ratio_grad`, no arrays."""
    d1, g1 = _det_grad3(c, n0, n1, n2)
    d2, g2 = _det_grad3(ce, n0, n1, n2)
    return d1 / d2, ((g1[0] * d2 - d1 * g2[0]) / (d2 * d2), (g1[1] * d2 - d1 * g2[1]) / (d2 * d2),
                     (g1[2] * d2 - d1 * g2[2]) / (d2 * d2))


@nb.njit(cache=True)
def _ratio_grad(c, ce, n, grad):
    """r = det A(n) / det A^e(n) and grad (3,) = dr/dn."""
    r, g = _ratio_grad3(c, ce, n[0], n[1], n[2])
    for m in range(3):
        grad[m] = g[m]
    return r


@nb.njit(cache=True, inline="always")
def _ratio3(c, ce, n0, n1, n2):
    """det A(n) / det A^e(n) for n = (n0, n1, n2), no arrays."""
    d1, _ = _cofactor9(_acoustic9(c, n0, n1, n2))
    d2, _ = _cofactor9(_acoustic9(ce, n0, n1, n2))
    return d1 / d2


@nb.njit(cache=True)
def _ratio(c, ce, n):
    """det A(n) / det A^e(n)."""
    return _ratio3(c, ce, n[0], n[1], n[2])


@nb.njit(cache=True)
def det_ratios(c, ce, normals):
    """det A(n) / det A^e(n) at each row of normals (k, 3); returns (k,)."""
    out = np.empty(normals.shape[0])
    for i in range(normals.shape[0]):
        out[i] = _ratio(c, ce, normals[i])
    return out


# --------------------------------------------------------------------------------------------
# plane strain: sweep, then bisection on d r / d theta around each local minimum
# --------------------------------------------------------------------------------------------


@nb.njit(cache=True)
def _dtheta(c, ce, t):
    """d r / d theta at n = (cos t, sin t, 0)."""
    _, g = _ratio_grad3(c, ce, math.cos(t), math.sin(t), 0.0)
    return -math.sin(t) * g[0] + math.cos(t) * g[1]


@nb.njit(cache=True)
def _plane_strain_minima(c, ce, n_sweep, theta_out, ratio_out):
    """Local minima of r(theta) over [0, pi): fills theta_out, ratio_out; returns their count.

    A sweep point is a minimum if r is strictly below its left and not above its right neighbour
    (periodic); it is refined by bisection of dr/dtheta on [t - h, t + h] where the sign changes.
    """
    return _plane_strain_minima_swept(c, ce, n_sweep, _elastic_sweep(ce, n_sweep), theta_out, ratio_out)


@nb.njit(cache=True)
def _elastic_sweep(ce, n_sweep):
    """(n_sweep, 3): cos t, sin t and det A^e(n) at the sweep's normals t = i pi / n_sweep."""
    h = math.pi / n_sweep
    out = np.empty((n_sweep, 3))
    for i in range(n_sweep):
        t = i * h
        out[i, 0] = math.cos(t)
        out[i, 1] = math.sin(t)
        out[i, 2] = _cofactor9(_acoustic9(ce, out[i, 0], out[i, 1], 0.0))[0]
    return out


@nb.njit(cache=True)
def _plane_strain_minima_swept(c, ce, n_sweep, sweep, theta_out, ratio_out):
    """:func:`_plane_strain_minima` with the elastic part of the sweep (:func:`_elastic_sweep`, the
    same at every point) given: det A(n) / det A^e(n) with the same values, so the same bits."""
    h = math.pi / n_sweep
    r = np.empty(n_sweep)
    for i in range(n_sweep):
        r[i] = _cofactor9(_acoustic9(c, sweep[i, 0], sweep[i, 1], 0.0))[0] / sweep[i, 2]
    count = 0
    for i in range(n_sweep):
        if not (r[i] < r[(i - 1) % n_sweep] and r[i] <= r[(i + 1) % n_sweep]):
            continue
        lo, hi = i * h - h, i * h + h
        t = i * h
        if _dtheta(c, ce, lo) < 0.0 and _dtheta(c, ce, hi) > 0.0:
            for _ in range(200):
                mid = 0.5 * (lo + hi)
                if mid <= lo or mid >= hi:
                    break
                if _dtheta(c, ce, mid) > 0.0:
                    hi = mid
                else:
                    lo = mid
            t = 0.5 * (lo + hi)
        t = t % math.pi
        theta_out[count] = t
        ratio_out[count] = _ratio3(c, ce, math.cos(t), math.sin(t), 0.0)
        count += 1
    return count


# --------------------------------------------------------------------------------------------
# 3D: sweep over the sphere, then Newton on the tangent plane (analytic gradient, FD Hessian)
# --------------------------------------------------------------------------------------------


@nb.njit(cache=True)
def _dot3(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@nb.njit(cache=True)
def _chart(n, e1, e2):
    """Fill e1, e2 (3,) so that (n, e1, e2) is orthonormal (n a unit vector)."""
    k = 0
    for j in range(1, 3):
        if abs(n[j]) < abs(n[k]):
            k = j
    for i in range(3):
        e1[i] = -n[k] * n[i]
    e1[k] += 1.0
    ln = math.sqrt(_dot3(e1, e1))
    for i in range(3):
        e1[i] /= ln
    e2[0] = n[1] * e1[2] - n[2] * e1[1]
    e2[1] = n[2] * e1[0] - n[0] * e1[2]
    e2[2] = n[0] * e1[1] - n[1] * e1[0]


@nb.njit(cache=True)
def _chart_point(n, e1, e2, u, v, m):
    """m = (n + u e1 + v e2) / |.|; returns the length before normalization."""
    for i in range(3):
        m[i] = n[i] + u * e1[i] + v * e2[i]
    lm = math.sqrt(_dot3(m, m))
    for i in range(3):
        m[i] /= lm
    return lm


@nb.njit(cache=True)
def _chart_grad(c, ce, n, e1, e2, u, v, out):
    """r and (dr/du, dr/dv) at m = n + u e1 + v e2 normalized."""
    m = np.empty(3)
    g = np.empty(3)
    lm = _chart_point(n, e1, e2, u, v, m)
    r = _ratio_grad(c, ce, m, g)
    gm = _dot3(g, m)
    for i in range(3):
        g[i] = (g[i] - gm * m[i]) / lm  # tangential part, through the normalization
    out[0] = _dot3(g, e1)
    out[1] = _dot3(g, e2)
    return r


@nb.njit(cache=True)
def _refine_sphere(c, ce, n0):
    """Local minimum of r on the unit sphere from n0 (3,): damped Newton in a moving chart.

    Analytic gradient, Hessian by central differences of it (step 1e-5 rad), backtracking on r.
    """
    zero = np.zeros(3)
    n = np.empty(3)
    _chart_point(n0, zero, zero, 0.0, 0.0, n)  # normalize (e1 = e2 = 0 here)
    e1, e2, m = np.empty(3), np.empty(3), np.empty(3)
    g, gp, gm = np.empty(2), np.empty(2), np.empty(2)
    hs = 1.0e-5
    for _ in range(60):
        _chart(n, e1, e2)
        r0 = _chart_grad(c, ce, n, e1, e2, 0.0, 0.0, g)
        _chart_grad(c, ce, n, e1, e2, hs, 0.0, gp)
        _chart_grad(c, ce, n, e1, e2, -hs, 0.0, gm)
        h00, h10 = (gp[0] - gm[0]) / (2.0 * hs), (gp[1] - gm[1]) / (2.0 * hs)
        _chart_grad(c, ce, n, e1, e2, 0.0, hs, gp)
        _chart_grad(c, ce, n, e1, e2, 0.0, -hs, gm)
        h01, h11 = (gp[0] - gm[0]) / (2.0 * hs), (gp[1] - gm[1]) / (2.0 * hs)
        off = 0.5 * (h01 + h10)
        det = h00 * h11 - off * off
        if det > 0.0 and h00 > 0.0:
            du = -(h11 * g[0] - off * g[1]) / det
            dv = -(h00 * g[1] - off * g[0]) / det
        else:  # not convex here: steepest descent, 0.05 rad
            gn = math.sqrt(g[0] * g[0] + g[1] * g[1])
            if gn == 0.0:
                break
            du, dv = -0.05 * g[0] / gn, -0.05 * g[1] / gn
        step = math.sqrt(du * du + dv * dv)
        if step > 0.1:
            du, dv = 0.1 * du / step, 0.1 * dv / step
            step = 0.1
        alpha = 1.0
        for _ls in range(30):
            _chart_point(n, e1, e2, alpha * du, alpha * dv, m)
            if _ratio(c, ce, m) <= r0 + 1.0e-15 * max(abs(r0), 1.0):
                break
            alpha *= 0.5
        for i in range(3):
            n[i] = m[i]
        if alpha * step < 1.0e-13:
            break
    return n


@nb.njit(cache=True)
def _sphere_point(i, j, n_polar, n_azimuth, out):
    """Grid normal: polar (i + 1/2) pi / n_polar, azimuth 2 pi j / n_azimuth."""
    th = math.pi * (i + 0.5) / n_polar
    ph = 2.0 * math.pi * j / n_azimuth
    out[0] = math.sin(th) * math.cos(ph)
    out[1] = math.sin(th) * math.sin(ph)
    out[2] = math.cos(th)


@nb.njit(cache=True)
def _sphere_candidates(c, ce, n_polar, n_azimuth, cand):
    """Local minima of r on a (polar, azimuth) grid of the sphere, the lowest cand.shape[0] of them.

    Fills cand (k, 3) and returns how many; ties go to the lower flat index (symmetric grids tie).
    """
    r = np.empty((n_polar, n_azimuth))
    pt = np.empty(3)
    for i in range(n_polar):
        for j in range(n_azimuth):
            _sphere_point(i, j, n_polar, n_azimuth, pt)
            r[i, j] = _ratio(c, ce, pt)
    cval = np.empty(cand.shape[0])
    count = 0
    best_i, best_j = 0, 0
    for i in range(n_polar):
        for j in range(n_azimuth):
            if r[i, j] < r[best_i, best_j]:
                best_i, best_j = i, j
            is_min = True
            for di in range(-1, 2):
                ii = i + di
                if ii < 0 or ii >= n_polar:
                    continue
                for dj in range(-1, 2):
                    jj = (j + dj) % n_azimuth
                    if di == 0 and dj == 0:
                        continue
                    rn = r[ii, jj]
                    if rn < r[i, j] or (rn == r[i, j] and ii * n_azimuth + jj < i * n_azimuth + j):
                        is_min = False
            if not is_min:
                continue
            slot = count
            if count == cand.shape[0]:  # full: replace the worst kept one if this is lower
                slot = 0
                for k in range(1, count):
                    if cval[k] > cval[slot]:
                        slot = k
                if not r[i, j] < cval[slot]:
                    continue
            else:
                count += 1
            _sphere_point(i, j, n_polar, n_azimuth, pt)
            for k in range(3):
                cand[slot, k] = pt[k]
            cval[slot] = r[i, j]
    if count == 0:  # flat: the lowest grid point
        _sphere_point(best_i, best_j, n_polar, n_azimuth, pt)
        for k in range(3):
            cand[0, k] = pt[k]
        count = 1
    return count


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


# --------------------------------------------------------------------------------------------
# screening many points at once (meshes of many cells)
# --------------------------------------------------------------------------------------------


@nb.njit(cache=True, parallel=True)
def screen_plane_strain(sigma, p, ce, n_sweep):
    """Min over a sweep of n_sweep in-plane normals of det A / det A^e (eq. 7-8, f and g at each
    stress), for many points: sigma (n, 6) [Pa] -> (n,). A coarse bound from above of the true
    minimum (within the sweep's resolution): refine with localization_plane_strain where it is small.
    The normals and det A^e(n) are the same at every point: computed once (same bits as per point).
    """
    n = sigma.shape[0]
    out = np.empty(n)
    normals = np.zeros((n_sweep, 3))
    det_e = np.empty(n_sweep)
    a = np.empty((3, 3))
    cof = np.empty((3, 3))
    for k in range(n_sweep):
        t = np.pi * k / n_sweep
        normals[k, 0] = math.cos(t)
        normals[k, 1] = math.sin(t)
        _acoustic(ce, normals[k], a)
        det_e[k] = _cofactor(a, cof)
    n_chunks = max(1, min(n, 256))
    for ch in nb.prange(n_chunks):
        ai = np.empty((3, 3))
        ci = np.empty((3, 3))
        for i in range(ch * n // n_chunks, (ch + 1) * n // n_chunks):
            c = dp.perfectly_plastic_tangent(ce, dp.yield_gradient(sigma[i], p), dp.potential_gradient(sigma[i], p))
            best = np.inf
            for k in range(n_sweep):
                _acoustic(c, normals[k], ai)
                r = _cofactor(ai, ci) / det_e[k]
                if r < best:
                    best = r
            out[i] = best
    return out


MAX_MINIMA = 16  # local minima kept per point by minima_plane_strain (more: the caller falls back)


@nb.njit(cache=True, parallel=True)
def minima_plane_strain(sigma, p, ce, n_sweep, theta_out, ratio_out, count_out):
    """The plane-strain minima of :func:`localization_plane_strain` at many stresses sigma (n, 6)
    [Pa] at once (tangent of eq. 8 with f and g at each stress, as :func:`perfectly_plastic_tangent_at`
    with ce = law.elastic_matrix(), p = law.as_array()): theta_out, ratio_out (n, MAX_MINIMA) the
    angles [rad] and ratios, count_out (n,) how many (> MAX_MINIMA: not stored). Same compiled
    search, so the same values as the one-point path."""
    n = sigma.shape[0]
    sweep = _elastic_sweep(ce, n_sweep)
    for i in nb.prange(n):
        c = dp.perfectly_plastic_tangent(ce, dp.yield_gradient(sigma[i], p), dp.potential_gradient(sigma[i], p))
        th = np.empty(n_sweep)
        rr = np.empty(n_sweep)
        k = _plane_strain_minima_swept(c, ce, n_sweep, sweep, th, rr)
        if k == 0:
            th[0], rr[0], k = 0.0, _ratio(c, ce, np.array([1.0, 0.0, 0.0])), 1
        count_out[i] = k
        for j in range(min(k, theta_out.shape[1])):
            theta_out[i, j] = th[j]
            ratio_out[i, j] = rr[j]


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
