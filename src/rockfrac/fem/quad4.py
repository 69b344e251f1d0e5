"""Bilinear quadrilateral (Q4) with 2x2 Gauss quadrature, plane strain, small strain.

Voigt order (xx, yy, xy) with engineering shear strain; element dofs ordered (u0x, u0y, u1x, ...).
"""

from __future__ import annotations

import numba as nb
import numpy as np

_G = 1.0 / np.sqrt(3.0)
GAUSS_XI = np.array([[-_G, -_G], [_G, -_G], [_G, _G], [-_G, _G]])  # (4 points, 2)
GAUSS_W = np.ones(4)
NODE_XI = np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]])


def plane_strain_elasticity(E: float, nu: float) -> np.ndarray:
    """Plane-strain elasticity matrix (3, 3) in Voigt (xx, yy, xy) with engineering shear [Pa]."""
    lam = E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu))
    mu = E / (2.0 * (1.0 + nu))
    return np.array([[lam + 2 * mu, lam, 0.0], [lam, lam + 2 * mu, 0.0], [0.0, 0.0, mu]])


def shape_gradients_ref() -> np.ndarray:
    """dN_a/dxi_j at the Gauss points, shape (4 points, 4 nodes, 2)."""
    xi = GAUSS_XI
    dn = np.empty((4, 4, 2))
    for a in range(4):
        dn[:, a, 0] = 0.25 * NODE_XI[a, 0] * (1.0 + NODE_XI[a, 1] * xi[:, 1])
        dn[:, a, 1] = 0.25 * NODE_XI[a, 1] * (1.0 + NODE_XI[a, 0] * xi[:, 0])
    return dn


DN_REF = shape_gradients_ref()


@nb.njit(cache=True, inline="always")
def _b_matrix(x: np.ndarray, dn_ref: np.ndarray, b: np.ndarray) -> float:
    """Fill B (3, 8) at one Gauss point of an element with nodes x (4, 2); return det J."""
    j00 = j01 = j10 = j11 = 0.0
    for a in range(4):
        j00 += dn_ref[a, 0] * x[a, 0]
        j01 += dn_ref[a, 0] * x[a, 1]
        j10 += dn_ref[a, 1] * x[a, 0]
        j11 += dn_ref[a, 1] * x[a, 1]
    det = j00 * j11 - j01 * j10
    for a in range(4):
        # grad N = J^-1 dN/dxi with J_ij = dx_j/dxi_i
        dx = (j11 * dn_ref[a, 0] - j01 * dn_ref[a, 1]) / det
        dy = (-j10 * dn_ref[a, 0] + j00 * dn_ref[a, 1]) / det
        b[0, 2 * a] = dx
        b[0, 2 * a + 1] = 0.0
        b[1, 2 * a] = 0.0
        b[1, 2 * a + 1] = dy
        b[2, 2 * a] = dy
        b[2, 2 * a + 1] = dx
    return det


@nb.njit(cache=True, parallel=True)
def elastic_stiffness(x: np.ndarray, d: np.ndarray, dn_ref: np.ndarray) -> np.ndarray:
    """Element stiffness matrices (n_el, 8, 8) [N/m per unit thickness] of linear elastic Q4s.

    x: (n_el, 4, 2) nodal coordinates; d: (3, 3) elasticity matrix.
    """
    n_el = x.shape[0]
    ke = np.zeros((n_el, 8, 8))
    for e in nb.prange(n_el):
        b = np.empty((3, 8))
        db = np.empty((3, 8))
        for q in range(4):
            det = _b_matrix(x[e], dn_ref[q], b)
            if det <= 0.0:
                ke[e, 0, 0] = np.nan  # flagged: inverted element
            for i in range(3):
                for j in range(8):
                    s = 0.0
                    for k in range(3):
                        s += d[i, k] * b[k, j]
                    db[i, j] = s * det
            for i in range(8):
                for j in range(8):
                    s = 0.0
                    for k in range(3):
                        s += b[k, i] * db[k, j]
                    ke[e, i, j] += s
    return ke


@nb.njit(cache=True, parallel=True)
def gauss_strains(x: np.ndarray, u: np.ndarray, dn_ref: np.ndarray) -> np.ndarray:
    """Strains (n_el, 4, 3) at the Gauss points, Voigt (xx, yy, xy) engineering shear.

    x: (n_el, 4, 2) nodes; u: (n_el, 8) element displacements.
    """
    n_el = x.shape[0]
    eps = np.zeros((n_el, 4, 3))
    for e in nb.prange(n_el):
        b = np.empty((3, 8))
        for q in range(4):
            _b_matrix(x[e], dn_ref[q], b)
            for i in range(3):
                s = 0.0
                for j in range(8):
                    s += b[i, j] * u[e, j]
                eps[e, q, i] = s
    return eps


def gauss_points(x: np.ndarray) -> np.ndarray:
    """Physical coordinates (n_el, 4, 2) of the Gauss points of elements with nodes x (n_el, 4, 2)."""
    n = np.array(
        [[0.25 * (1 + NODE_XI[a, 0] * g[0]) * (1 + NODE_XI[a, 1] * g[1]) for a in range(4)] for g in GAUSS_XI]
    )  # (4 gp, 4 nodes)
    return np.einsum("qa,eai->eqi", n, x)
