"""Small-strain kinematics of isoparametric solids: physical gradients, Voigt strains, B^T s, B^T C B.

Voigt order of the full strain/stress 6-vectors: (xx, yy, zz, xy, yz, xz), engineering shear
strains (gamma_xy = 2 eps_xy). A 2D (plane-strain) element works on the reduced components
(xx, yy, xy), i.e. VOIGT_2D of the 6-vector; eps_zz = eps_yz = eps_xz = 0.
Element dofs are ordered node by node: (u_0x, u_0y[, u_0z], u_1x, ...).
"""

from __future__ import annotations

import numba as nb
import numpy as np

from rockfrac.compiled import inner, kernel
from rockfrac.fem.reference import ReferenceElement
from rockfrac.threads import parallel_kernel

VOIGT_2D = np.array([0, 1, 3])  # positions of (xx, yy, xy) in the 6-vector
VOIGT_3D = np.arange(6)


def voigt_index(dim: int) -> np.ndarray:
    """Positions of the element's strain components in the full Voigt 6-vector."""
    return VOIGT_2D if dim == 2 else VOIGT_3D


@parallel_kernel(cost=0.18e-6)  # s per item, one thread (benchmarks/thread_rule.py)
def gradients(x: np.ndarray, dn_ref: np.ndarray, w_ref: np.ndarray):
    """Physical shape gradients (n_el, n_qp, n_nodes, dim) and det J * w (n_el, n_qp).

    x: (n_el, n_nodes, dim) nodal coordinates [m]; dn_ref: (n_qp, n_nodes, dim) dN/dxi;
    w_ref: (n_qp,) Gauss weights. A non-positive det J leaves its weight <= 0 (checked by the caller).
    """
    n_el, n_nodes, dim = x.shape
    n_qp = dn_ref.shape[0]
    grads = np.empty((n_el, n_qp, n_nodes, dim))
    wdet = np.empty((n_el, n_qp))
    for e in nb.prange(n_el):
        jac = np.zeros((dim, dim))
        inv = np.empty((dim, dim))
        for q in range(n_qp):
            for i in range(dim):  # J_ij = dx_j / dxi_i
                for j in range(dim):
                    s = 0.0
                    for a in range(n_nodes):
                        s += dn_ref[q, a, i] * x[e, a, j]
                    jac[i, j] = s
            if dim == 2:
                det = jac[0, 0] * jac[1, 1] - jac[0, 1] * jac[1, 0]
                inv[0, 0] = jac[1, 1] / det
                inv[0, 1] = -jac[0, 1] / det
                inv[1, 0] = -jac[1, 0] / det
                inv[1, 1] = jac[0, 0] / det
            else:
                det = (jac[0, 0] * (jac[1, 1] * jac[2, 2] - jac[1, 2] * jac[2, 1])
                       - jac[0, 1] * (jac[1, 0] * jac[2, 2] - jac[1, 2] * jac[2, 0])
                       + jac[0, 2] * (jac[1, 0] * jac[2, 1] - jac[1, 1] * jac[2, 0]))
                inv[0, 0] = (jac[1, 1] * jac[2, 2] - jac[1, 2] * jac[2, 1]) / det
                inv[0, 1] = (jac[0, 2] * jac[2, 1] - jac[0, 1] * jac[2, 2]) / det
                inv[0, 2] = (jac[0, 1] * jac[1, 2] - jac[0, 2] * jac[1, 1]) / det
                inv[1, 0] = (jac[1, 2] * jac[2, 0] - jac[1, 0] * jac[2, 2]) / det
                inv[1, 1] = (jac[0, 0] * jac[2, 2] - jac[0, 2] * jac[2, 0]) / det
                inv[1, 2] = (jac[0, 2] * jac[1, 0] - jac[0, 0] * jac[1, 2]) / det
                inv[2, 0] = (jac[1, 0] * jac[2, 1] - jac[1, 1] * jac[2, 0]) / det
                inv[2, 1] = (jac[0, 1] * jac[2, 0] - jac[0, 0] * jac[2, 1]) / det
                inv[2, 2] = (jac[0, 0] * jac[1, 1] - jac[0, 1] * jac[1, 0]) / det
            wdet[e, q] = det * w_ref[q]
            for a in range(n_nodes):  # dN/dx_j = (J^-1)_ji dN/dxi_i
                for j in range(dim):
                    s = 0.0
                    for i in range(dim):
                        s += inv[j, i] * dn_ref[q, a, i]
                    grads[e, q, a, j] = s
    return grads, wdet


def element_gradients(x: np.ndarray, ref: ReferenceElement) -> tuple[np.ndarray, np.ndarray]:
    """Gradients and weights of elements with nodes x (n_el, n_nodes, dim) on reference ``ref``."""
    return gradients(np.ascontiguousarray(x, dtype=np.float64), ref.shape_gradients(ref.points), ref.weights)


@kernel
def b_matrix(g: np.ndarray, b: np.ndarray) -> None:
    """Fill B (n_voigt, n_nodes * dim) from gradients g (n_nodes, dim): eps_reduced = B u_e.

    Rows (xx, yy, xy) in 2D, (xx, yy, zz, xy, yz, xz) in 3D, engineering shear.
    """
    n_nodes, dim = g.shape
    b[:, :] = 0.0
    for a in range(n_nodes):
        c = dim * a
        if dim == 2:
            b[0, c] = g[a, 0]
            b[1, c + 1] = g[a, 1]
            b[2, c] = g[a, 1]
            b[2, c + 1] = g[a, 0]
        else:
            b[0, c] = g[a, 0]
            b[1, c + 1] = g[a, 1]
            b[2, c + 2] = g[a, 2]
            b[3, c] = g[a, 1]
            b[3, c + 1] = g[a, 0]
            b[4, c + 1] = g[a, 2]
            b[4, c + 2] = g[a, 1]
            b[5, c] = g[a, 2]
            b[5, c + 2] = g[a, 0]


@inner
def add_btcb(b, w, c, idx, cb, ke):
    """ke += w B^T C B at one point: B (nv, nd), C read at (idx[k], idx[l]) (the element's Voigt
    components of a 6 x 6 modulus, or idx = 0..nv-1 of a reduced one); cb (nv, nd) is scratch.
    The one B^T C B of every solid element (elastic blocks, Drucker-Prager and EDE cells)."""
    nv, nd = b.shape
    for k in range(nv):
        for j in range(nd):
            s = 0.0
            for l in range(nv):
                s += c[idx[k], idx[l]] * b[l, j]
            cb[k, j] = w * s
    for i in range(nd):
        for j in range(nd):
            s = 0.0
            for k in range(nv):
                s += b[k, i] * cb[k, j]
            ke[i, j] += s


@inner
def add_bts(b, w, sig6, idx, fe):
    """fe += w B^T sigma at one point (sigma a Voigt 6-vector, read at idx)."""
    nv, nd = b.shape
    for i in range(nd):
        s = 0.0
        for k in range(nv):
            s += b[k, i] * sig6[idx[k]]
        fe[i] += w * s


@inner
def plane_add_btcb(g, w, c, shear, cb, ke):
    """:func:`add_btcb` of a plane cell from its gradients g (n_nodes, 2): B's rows (xx, yy, xy) have two
    nonzeros per column, skipped; the same sums in the same order (the same bits). c's rows and
    columns (xx, yy) are 0, 1 and the shear one is ``shear`` (2 for a 3 x 3 modulus, 3 for a Voigt 6 x 6)."""
    n_nodes = g.shape[0]
    nd = 2 * n_nodes
    for a in range(n_nodes):
        gx, gy = g[a, 0], g[a, 1]
        for k in range(3):
            ik = shear if k == 2 else k
            cb[k, 2 * a] = w * (c[ik, 0] * gx + c[ik, shear] * gy)
            cb[k, 2 * a + 1] = w * (c[ik, 1] * gy + c[ik, shear] * gx)
    for a in range(n_nodes):
        gx, gy = g[a, 0], g[a, 1]
        for j in range(nd):
            ke[2 * a, j] += gx * cb[0, j] + gy * cb[2, j]
            ke[2 * a + 1, j] += gy * cb[1, j] + gx * cb[2, j]


@inner
def plane_add_bts(g, w, sig6, fe):
    """:func:`add_bts` of a plane cell from its gradients g (n_nodes, 2), B's zeros skipped."""
    for a in range(g.shape[0]):
        gx, gy = g[a, 0], g[a, 1]
        fe[2 * a] += w * (gx * sig6[0] + gy * sig6[3])
        fe[2 * a + 1] += w * (gy * sig6[1] + gx * sig6[3])


@inner
def point_strain(b, ue, idx, eps6):
    """Full Voigt strain eps6 (6,) = B u_e on the components idx, zero elsewhere (plane strain)."""
    nv, nd = b.shape
    eps6[:] = 0.0
    for k in range(nv):
        s = 0.0
        for j in range(nd):
            s += b[k, j] * ue[j]
        eps6[idx[k]] = s


@inner
def plane_point_strain(g, ue, eps6):
    """:func:`point_strain` of a plane cell from its gradients g (n_nodes, 2), B's zeros skipped
    (the same sums in the same order, so the same bits)."""
    exx = 0.0
    eyy = 0.0
    gxy = 0.0
    for a in range(g.shape[0]):
        gx, gy = g[a, 0], g[a, 1]
        exx += gx * ue[2 * a]
        eyy += gy * ue[2 * a + 1]
        gxy += gy * ue[2 * a]
        gxy += gx * ue[2 * a + 1]
    eps6[:] = 0.0
    eps6[0] = exx
    eps6[1] = eyy
    eps6[3] = gxy


@parallel_kernel(cost=0.3e-6)  # s per item, one thread (an estimate: no benchmark example calls it)
def elastic_blocks(grads: np.ndarray, wdet: np.ndarray, d: np.ndarray) -> np.ndarray:
    """Element stiffness matrices (n_el, nd, nd) = sum_q w det J B^T D B [N/m, per unit thickness in 2D].

    d: (n_voigt, n_voigt) elasticity in the element's Voigt components (3x3 plane strain, 6x6 3D).
    """
    n_el, n_qp, n_nodes, dim = grads.shape
    nv = d.shape[0]
    nd = n_nodes * dim
    ke = np.zeros((n_el, nd, nd))
    idx = np.arange(nv)
    for e in nb.prange(n_el):
        b = np.empty((nv, nd))
        db = np.empty((nv, nd))
        for q in range(n_qp):
            b_matrix(grads[e, q], b)
            add_btcb(b, wdet[e, q], d, idx, db, ke[e])
    return ke


@parallel_kernel(cost=0.1e-6)  # s per item, one thread (an estimate: no benchmark example calls it)
def strains(grads: np.ndarray, ue: np.ndarray) -> np.ndarray:
    """Full Voigt strains (n_el, n_qp, 6) at the Gauss points from element dofs ue (n_el, nd)."""
    n_el, n_qp, n_nodes, dim = grads.shape
    nv = 3 if dim == 2 else 6
    idx = np.array([0, 1, 3]) if dim == 2 else np.arange(6)
    eps = np.zeros((n_el, n_qp, 6))
    for e in nb.prange(n_el):
        b = np.empty((nv, n_nodes * dim))
        for q in range(n_qp):
            b_matrix(grads[e, q], b)
            for i in range(nv):
                s = 0.0
                for j in range(n_nodes * dim):
                    s += b[i, j] * ue[e, j]
                eps[e, q, idx[i]] = s
    return eps


@kernel
def elastic_assemble(grads: np.ndarray, wdet: np.ndarray, d: np.ndarray, slots: np.ndarray,
                     data: np.ndarray) -> None:
    """data[slots[e]] += sum_q w det J B^T D B for every cell e: the stiffness values and their scatter
    into an existing CSR pattern in one pass, no (n_el, nd, nd) array [N/m].

    Serial (the scatter would race between threads); equal to the last bit to
    ``scatter_matrix(data, slots, elastic_blocks(grads, wdet, d))`` (plane cells: zeros of B
    skipped, same sums; 3D: the same loops).
    """
    n_el, n_qp, n_nodes, dim = grads.shape
    nv = d.shape[0]
    nd = n_nodes * dim
    ke = np.empty((nd, nd))
    b = np.empty((nv, nd))
    db = np.empty((nv, nd))
    idx = np.arange(nv)
    for e in range(n_el):
        ke[:, :] = 0.0
        for q in range(n_qp):
            if dim == 2:
                plane_add_btcb(grads[e, q], wdet[e, q], d, np.int64(2), db, ke)
            else:
                b_matrix(grads[e, q], b)
                add_btcb(b, wdet[e, q], d, idx, db, ke)
        for i in range(nd):
            for j in range(nd):
                data[slots[e, i, j]] += ke[i, j]


def internal_forces(grads: np.ndarray, wdet: np.ndarray, sigma: np.ndarray) -> np.ndarray:
    """Element vectors sum_q w B^T sigma (n_el, nd) of Gauss-point stresses sigma (n_el, n_qp, 6)
    [Pa] (Voigt xx, yy, zz, xy, yz, xz); NumPy, for set-up (initial stress), not the Newton loop."""
    n_el, n_qp, n_nodes, dim = grads.shape
    gw = grads * wdet[:, :, None, None]
    s = sigma
    gx, gy = gw[..., 0], gw[..., 1]
    if dim == 2:
        fx = np.einsum("eqa,eq->ea", gx, s[..., 0]) + np.einsum("eqa,eq->ea", gy, s[..., 3])
        fy = np.einsum("eqa,eq->ea", gy, s[..., 1]) + np.einsum("eqa,eq->ea", gx, s[..., 3])
        return np.stack([fx, fy], axis=2).reshape(n_el, 2 * n_nodes)
    gz = gw[..., 2]
    ein = lambda g, k: np.einsum("eqa,eq->ea", g, s[..., k])
    fx = ein(gx, 0) + ein(gy, 3) + ein(gz, 5)
    fy = ein(gy, 1) + ein(gx, 3) + ein(gz, 4)
    fz = ein(gz, 2) + ein(gy, 4) + ein(gx, 5)
    return np.stack([fx, fy, fz], axis=2).reshape(n_el, 3 * n_nodes)
