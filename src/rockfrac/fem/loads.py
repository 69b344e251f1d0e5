"""Consistent nodal loads: tractions on boundary edges (2D) and faces (3D), body forces, and the
tractions of a stress field on a boundary. Forces per unit thickness in 2D [N/m], N in 3D.

Edges (k, 2) run counter-clockwise around the body, so the outward normal of edge a -> b is
(dy, -dx)/L; faces are bilinear quadrilaterals (k, 4) with the outward right-hand normal
(x1 - x0) x (x3 - x0), or linear triangles (k, 3) with normal (x1 - x0) x (x2 - x0). Every
integral is exact for the linear (2D), bilinear and triangular (3D) geometry with tractions
varying linearly along the side (two Gauss points per direction; three points on a triangle).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from rockfrac.fem.reference import QUAD4, TRI3, TRIANGLE_RULE, ReferenceElement

_G = 1.0 / np.sqrt(3.0)
LINE_POINTS = np.array([0.5 * (1.0 - _G), 0.5 * (1.0 + _G)])  # Gauss points on [0, 1], weights 1/2

#: A stress field: points (m, dim) -> Voigt stresses (m, 6) [Pa] (xx, yy, zz, xy, yz, xz).
StressField = Callable[[np.ndarray], np.ndarray]


def _scatter(f: np.ndarray, nodes_of: np.ndarray, forces: np.ndarray, dim: int) -> None:
    """f[dim * node + i] += forces[..., i] for nodes_of (...,) and forces (..., dim)."""
    for i in range(dim):
        np.add.at(f, dim * nodes_of + i, forces[..., i])


def edge_pressure(nodes: np.ndarray, edges: np.ndarray, pressure: float, f: np.ndarray) -> None:
    """Add the nodal forces of a pressure [Pa] (positive pushing inward) on 2D edges: each end
    receives half the edge force -p n L."""
    if edges.size == 0:
        return
    d = nodes[edges[:, 1]] - nodes[edges[:, 0]]
    half = -0.5 * pressure * np.stack([d[:, 1], -d[:, 0]], axis=1)  # (k, 2) = -p n L / 2
    for end in (0, 1):
        np.add.at(f, 2 * edges[:, end], half[:, 0])
        np.add.at(f, 2 * edges[:, end] + 1, half[:, 1])


def edge_normals(nodes: np.ndarray, edges: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Outward unit normals (k, 2) and lengths (k,) of counter-clockwise boundary edges."""
    d = nodes[edges[:, 1], :2] - nodes[edges[:, 0], :2]
    length = np.linalg.norm(d, axis=1)
    return np.stack([d[:, 1], -d[:, 0]], axis=1) / length[:, None], length


def edge_traction(nodes: np.ndarray, edges: np.ndarray, traction: np.ndarray, f: np.ndarray) -> None:
    """Add the nodal forces of a uniform traction vector (2,) [Pa] on 2D edges: t L / 2 per node."""
    if edges.size == 0:
        return
    _, length = edge_normals(nodes, edges)
    half = 0.5 * length[:, None] * np.asarray(traction, dtype=float)[None, :]
    _scatter(f, edges, np.stack([half, half], axis=1), 2)


def edge_stress_traction(nodes: np.ndarray, edges: np.ndarray, stress: StressField, f: np.ndarray,
                         factor: np.ndarray | float = 1.0) -> None:
    """Add the consistent nodal forces of the traction sigma . n of a stress field on 2D boundary
    edges (n outward), times ``factor`` (scalar or one per edge)."""
    if edges.size == 0:
        return
    n, length = edge_normals(nodes, edges)
    x0, x1 = nodes[edges[:, 0], :2], nodes[edges[:, 1], :2]
    scale = np.broadcast_to(np.asarray(factor, dtype=float), (edges.shape[0],))
    forces = np.zeros((edges.shape[0], 2, 2))
    for s in LINE_POINTS:
        x = (1.0 - s) * x0 + s * x1
        sig = stress(x)
        t = np.stack([sig[:, 0] * n[:, 0] + sig[:, 3] * n[:, 1], sig[:, 3] * n[:, 0] + sig[:, 1] * n[:, 1]], axis=1)
        w = 0.5 * length * scale
        forces[:, 0] += ((1.0 - s) * w)[:, None] * t
        forces[:, 1] += (s * w)[:, None] * t
    _scatter(f, edges, forces, 2)


def face_rule(x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Shape values (qp, m), points (k, qp, 3) [m] and n dA times the Gauss weight (k, qp, 3) [m^2] of
    bilinear (m = 4, 2 x 2 points of weight 1) or triangular (m = 3, three points) faces with
    corners x (k, m, 3)."""
    if x.shape[1] == 3:
        pts, w = TRIANGLE_RULE
        ref = TRI3
    else:
        pts, w = QUAD4.points, QUAD4.weights
        ref = QUAD4
    shape, dn = ref.shape(pts), ref.shape_gradients(pts)
    xi = np.einsum("qa,kai->kqi", dn[:, :, 0], x)
    eta = np.einsum("qa,kai->kqi", dn[:, :, 1], x)
    nda = np.cross(xi, eta)
    if x.shape[1] == 3:
        nda = nda * w[None, :, None]
    return shape, np.einsum("qa,kai->kqi", shape, x), nda


def _face_geometry(nodes: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`face_rule` of the faces (k, m) of a mesh with these nodes."""
    return face_rule(nodes[faces])


def face_pressure(nodes: np.ndarray, faces: np.ndarray, pressure: float, f: np.ndarray) -> None:
    """Add the consistent nodal forces -p int N_a n dA of a pressure [Pa] (positive pushing inward)
    on 3D faces (exact for planar and warped bilinear faces)."""
    if faces.size == 0:
        return
    shape, _, nda = _face_geometry(nodes, faces)
    forces = -pressure * np.einsum("qa,kqi->kai", shape, nda)  # nda carries the Gauss weights
    for i in range(3):
        np.add.at(f, 3 * faces + i, forces[:, :, i])


def face_traction(nodes: np.ndarray, faces: np.ndarray, traction: np.ndarray, f: np.ndarray) -> None:
    """Add the nodal forces int N_a t dA of a uniform traction vector (3,) [Pa] on 3D faces."""
    if faces.size == 0:
        return
    shape, _, nda = _face_geometry(nodes, faces)
    area = np.linalg.norm(nda, axis=2)  # (k, qp): dA times the Gauss weight
    forces = np.einsum("qa,kq,i->kai", shape, area, np.asarray(traction, dtype=float))
    _scatter(f, faces, forces, 3)


def face_stress_traction(nodes: np.ndarray, faces: np.ndarray, stress: StressField, f: np.ndarray,
                         factor: np.ndarray | float = 1.0) -> None:
    """Add int N_a sigma . n dA of a stress field on 3D boundary faces (n outward), times ``factor``."""
    if faces.size == 0:
        return
    shape, x, nda = _face_geometry(nodes, faces)
    k = faces.shape[0]
    nq = shape.shape[0]
    sig = stress(x.reshape(-1, 3)).reshape(k, nq, 6)
    full = sig[..., [0, 3, 5, 3, 1, 4, 5, 4, 2]].reshape(k, nq, 3, 3)
    t = np.einsum("kqij,kqj->kqi", full, nda)
    scale = np.broadcast_to(np.asarray(factor, dtype=float), (k,))
    _scatter(f, faces, np.einsum("qa,kqi,k->kai", shape, t, scale), 3)


def nodal_volumes(nodes: np.ndarray, cells: np.ndarray, ref: ReferenceElement, wdet: np.ndarray) -> np.ndarray:
    """int N_a dV per cell node (n_el, n_nodes): the consistent lumping of a uniform body force."""
    return np.einsum("qa,eq->ea", ref.shape(ref.points), wdet)


def body_force(cells: np.ndarray, volumes: np.ndarray, density: float, gravity: np.ndarray, f: np.ndarray) -> None:
    """Add the nodal forces int N_a rho g dV of gravity (dim,) [m/s^2] on cells of one density
    [kg/m^3]; volumes from :func:`nodal_volumes`."""
    g = np.asarray(gravity, dtype=float)
    _scatter(f, cells, density * volumes[..., None] * g[None, None, :], g.shape[0])


def quadrature_points(nodes: np.ndarray, cells: np.ndarray, ref: ReferenceElement) -> np.ndarray:
    """Physical coordinates (n_el, n_qp, dim) of the cells' Gauss points."""
    return np.einsum("qa,ead->eqd", ref.shape(ref.points), nodes[cells])


def segment_pair_forces(x0: np.ndarray, x1: np.ndarray, stress: StressField) -> np.ndarray:
    """Consistent nodal forces (k, 2, 2) [N/m] at the ends x0, x1 (k, 2) of straight 2D segments of the
    traction sigma . n, n = rot90(x1 - x0) / L (the normal of a cohesive segment, minus to plus side):
    what the plus side of a crack along them transmits to its ends in the in-situ state."""
    d = x1 - x0
    length = np.linalg.norm(d, axis=1)
    n = np.stack([-d[:, 1], d[:, 0]], axis=1) / length[:, None]
    forces = np.zeros((x0.shape[0], 2, 2))
    for s in LINE_POINTS:
        sig = stress((1.0 - s) * x0 + s * x1)
        t = np.stack([sig[:, 0] * n[:, 0] + sig[:, 3] * n[:, 1], sig[:, 3] * n[:, 0] + sig[:, 1] * n[:, 1]], axis=1)
        forces[:, 0] += (0.5 * length * (1.0 - s))[:, None] * t
        forces[:, 1] += (0.5 * length * s)[:, None] * t
    return forces


def side_normals(nodes: np.ndarray, sides: np.ndarray) -> np.ndarray:
    """Outward unit normals (k, dim) of boundary edges (k, 2) or faces (k, 3|4) (fem.loads' orientations)."""
    if sides.shape[1] == 2:
        return edge_normals(nodes, sides)[0]
    x = nodes[sides]
    n = np.cross(x[:, 1] - x[:, 0], x[:, -1 if sides.shape[1] == 4 else 2] - x[:, 0])
    return n / np.linalg.norm(n, axis=1, keepdims=True)
