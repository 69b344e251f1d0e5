"""Plane-strain bifurcation kernels: minima of det A / det A^e over in-plane normals, many points."""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from rockfrac.compiled import inner, kernel
from rockfrac.laws import drucker_prager as dp
from rockfrac.laws.acoustic import (
    _acoustic,
    _acoustic9,
    _cofactor,
    _cofactor9,
    _ratio,
    _ratio3,
    _ratio_grad3,
    lowest_ratio,
)
from rockfrac.threads import parallel_kernel

# --------------------------------------------------------------------------------------------
# plane strain: sweep, then bisection on d r / d theta around each local minimum
# --------------------------------------------------------------------------------------------


@inner
def _dtheta(c, ce, t):
    """d r / d theta at n = (cos t, sin t, 0)."""
    _, g = _ratio_grad3(c, ce, math.cos(t), math.sin(t), 0.0)
    return -math.sin(t) * g[0] + math.cos(t) * g[1]


@kernel
def _plane_strain_minima(c, ce, n_sweep, theta_out, ratio_out):
    """Local minima of r(theta) over [0, pi): fills theta_out, ratio_out; returns their count.

    A sweep point is a minimum if r is strictly below its left and not above its right neighbour
    (periodic); it is refined by bisection of dr/dtheta on [t - h, t + h] where the sign changes.
    """
    return _plane_strain_minima_swept(c, ce, n_sweep, _elastic_sweep(ce, n_sweep), theta_out, ratio_out)


@inner
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


@inner
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
# screening many points at once (meshes of many cells)
# --------------------------------------------------------------------------------------------


@parallel_kernel(cost=3.9e-6)  # s per item, one thread (benchmarks/thread_rule.py)
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
            out[i] = lowest_ratio(c, normals, det_e, ai, ci)[0]
    return out


MAX_MINIMA = 16  # local minima kept per point by minima_plane_strain (more: the caller falls back)


@parallel_kernel(cost=38e-6)  # s per item, one thread (benchmarks/thread_rule.py)
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
