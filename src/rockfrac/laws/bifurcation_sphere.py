"""3D bifurcation kernels: local minima of det A / det A^e over the unit sphere (sweep, Newton). The
Drucker-Prager minimum at many points is rockfrac.laws.bifurcation_dp3d's closed form."""

from __future__ import annotations

import math

import numpy as np

from rockfrac.compiled import inner, kernel
from rockfrac.laws.acoustic import _ratio, _ratio_grad

# --------------------------------------------------------------------------------------------
# 3D: sweep over the sphere, then Newton on the tangent plane (analytic gradient, FD Hessian)
# --------------------------------------------------------------------------------------------


@inner
def _dot3(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@inner
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


@inner
def _chart_point(n, e1, e2, u, v, m):
    """m = (n + u e1 + v e2) / |.|; returns the length before normalization."""
    for i in range(3):
        m[i] = n[i] + u * e1[i] + v * e2[i]
    lm = math.sqrt(_dot3(m, m))
    for i in range(3):
        m[i] /= lm
    return lm


@inner
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


@kernel
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


@inner
def _sphere_point(i, j, n_polar, n_azimuth, out):
    """Grid normal: polar (i + 1/2) pi / n_polar, azimuth 2 pi j / n_azimuth."""
    th = math.pi * (i + 0.5) / n_polar
    ph = 2.0 * math.pi * j / n_azimuth
    out[0] = math.sin(th) * math.cos(ph)
    out[1] = math.sin(th) * math.sin(ph)
    out[2] = math.cos(th)


@kernel
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
