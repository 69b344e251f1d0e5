"""The exact minimum over unit normals of det A / det A^e (eq. 7-8) for the Drucker-Prager law in
3D, at many stresses, in closed form.

The perfectly plastic tangent is a rank-one update of the isotropic Ce, c = Ce - (Ce:g)(f:Ce) / h
with h = f:Ce:g, so A(n) = A^e(n) - (G n)(F n)^T / h with G = Ce:g, F = Ce:f (stress tensors) and

    det A / det A^e = 1 - (F n) . A^e(n)^-1 (G n) / h,   A^e(n)^-1 = (I - kappa n n) / mu,

kappa = (lambda + mu) / (lambda + 2 mu). For Drucker-Prager, f = sqrt(3/2) s^ + beta / sqrt(3) I
and g the same with b (s^ = s / |s|), so F = sqrt(3) K beta I + sqrt(6) mu s^, G = sqrt(3) K b I +
sqrt(6) mu s^ and h = 3 mu + 3 K beta b: F and G share the principal axes of the stress. There, with
x_i = n_i^2 (x >= 0, sum x = 1),

    det A / det A^e = 1 - [sum F_i G_i x_i - kappa (sum F_i x_i)(sum G_i x_i)] / (mu h),

a quadratic in x over a triangle: its largest bracket is at a vertex, at a stationary point of an
edge or at the interior stationary point, each in closed form (Ottosen & Runesson 1991 for the
same structure). The minimum is exact, where a search over a grid of normals bounds it from above.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from rockfrac.compiled import inner
from rockfrac.laws import drucker_prager as dp
from rockfrac.laws.drucker_prager import P_B, P_BETA
from rockfrac.threads import parallel_kernel


@inner
def _quadratic(c, f, g, kappa, x):
    """c . x - kappa (f . x)(g . x)."""
    fx = f[0] * x[0] + f[1] * x[1] + f[2] * x[2]
    gx = g[0] * x[0] + g[1] * x[1] + g[2] * x[2]
    return c[0] * x[0] + c[1] * x[1] + c[2] * x[2] - kappa * fx * gx


@inner
def _interior_stationary(c, f, g, kappa, x):
    """The stationary point of c . x - kappa (f . x)(g . x) on the plane sum x = 1: kappa (f g^T +
    g f^T) x + nu 1 = c, sum x = 1, by Gaussian elimination with partial pivoting. Fills x (3,) and
    returns False where the system is singular (then the maximum is on the triangle's boundary)."""
    m = np.zeros((4, 5))
    scale = 0.0
    for i in range(3):
        for k in range(3):
            m[i, k] = kappa * (f[i] * g[k] + g[i] * f[k])
            scale = max(scale, abs(m[i, k]))
        m[i, 3] = 1.0
        m[i, 4] = c[i]
        m[3, i] = 1.0
    m[3, 4] = 1.0
    tol = 1.0e-13 * max(scale, 1.0)
    for col in range(4):
        piv = col
        for r in range(col + 1, 4):
            if abs(m[r, col]) > abs(m[piv, col]):
                piv = r
        if abs(m[piv, col]) <= tol:
            return False
        if piv != col:
            for k in range(5):
                m[col, k], m[piv, k] = m[piv, k], m[col, k]
        for r in range(col + 1, 4):
            factor = m[r, col] / m[col, col]
            for k in range(col, 5):
                m[r, k] -= factor * m[col, k]
    sol = np.zeros(4)
    for r in range(3, -1, -1):
        acc = m[r, 4]
        for k in range(r + 1, 4):
            acc -= m[r, k] * sol[k]
        sol[r] = acc / m[r, r]
    for i in range(3):
        x[i] = sol[i]
    return True


@inner
def simplex_maximum(c, f, g, kappa):
    """max of c . x - kappa (f . x)(g . x) over x >= 0, sum x = 1 (c, f, g (3,)): vertices, the
    edges' stationary points and the interior one, whichever are in the triangle."""
    x = np.zeros(3)
    best = -np.inf
    for i in range(3):
        x[:] = 0.0
        x[i] = 1.0
        best = max(best, _quadratic(c, f, g, kappa, x))
    for i in range(3):
        for j in range(i + 1, 3):  # x_i = t, x_j = 1 - t: q(t) = q_j + a1 t + a2 t^2
            df, dg = f[i] - f[j], g[i] - g[j]
            a2 = -kappa * df * dg
            a1 = c[i] - c[j] - kappa * (f[j] * dg + g[j] * df)
            if a2 < 0.0:
                t = -a1 / (2.0 * a2)
                if 0.0 < t < 1.0:
                    x[:] = 0.0
                    x[i], x[j] = t, 1.0 - t
                    best = max(best, _quadratic(c, f, g, kappa, x))
    if _interior_stationary(c, f, g, kappa, x) and x[0] >= 0.0 and x[1] >= 0.0 and x[2] >= 0.0:
        best = max(best, _quadratic(c, f, g, kappa, x))
    return best


@inner
def _deviator_principal(sigma, out):
    """out (3,) the principal values of dev(sigma) / |dev(sigma)| (0 at the apex); sigma Voigt
    (xx, yy, zz, xy, yz, xz) [Pa]."""
    s = np.empty(6)
    _, sn = dp.deviator(sigma, s)
    if sn == 0.0:
        out[:] = 0.0
        return
    t = np.empty((3, 3))
    t[0, 0], t[1, 1], t[2, 2] = s[0] / sn, s[1] / sn, s[2] / sn
    t[0, 1] = t[1, 0] = s[3] / sn
    t[1, 2] = t[2, 1] = s[4] / sn
    t[0, 2] = t[2, 0] = s[5] / sn
    w = np.linalg.eigvalsh(t)
    for i in range(3):
        out[i] = w[i]


@inner
def min_ratio_dp_3d(sigma, p):
    """min over unit normals of det A / det A^e (eq. 7-8) with f, g of the Drucker-Prager law p at
    the stress sigma (6,) [Pa] (module doc) [-]."""
    k, mu = dp.moduli(p)
    lam = k - 2.0 * mu / 3.0
    kappa = (lam + mu) / (lam + 2.0 * mu)
    beta, b = p[P_BETA], p[P_B]
    sh = np.empty(3)
    _deviator_principal(sigma, sh)
    f = np.empty(3)
    g = np.empty(3)
    c = np.empty(3)
    for i in range(3):
        f[i] = math.sqrt(3.0) * k * beta + math.sqrt(6.0) * mu * sh[i]
        g[i] = math.sqrt(3.0) * k * b + math.sqrt(6.0) * mu * sh[i]
        c[i] = f[i] * g[i]
    h = 3.0 * mu + 3.0 * k * beta * b
    return 1.0 - simplex_maximum(c, f, g, kappa) / (mu * h)


@parallel_kernel(cost=2.0e-6)  # s per item, one thread (an estimate: a 3 x 3 eigenproblem and a 4 x 4 solve)
def min_ratios_dp_3d(sigma, p):
    """:func:`min_ratio_dp_3d` at every row of sigma (n, 6) [Pa] -> (n,)."""
    n = sigma.shape[0]
    out = np.empty(n)
    n_chunks = max(1, min(n, 256))
    for ch in nb.prange(n_chunks):
        for i in range(ch * n // n_chunks, (ch + 1) * n // n_chunks):
            out[i] = min_ratio_dp_3d(sigma[i], p)
    return out
