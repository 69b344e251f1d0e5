"""Boundary conditions: edge pressure loads (consistent nodal forces of linear edges)."""

from __future__ import annotations

import numpy as np


def edge_pressure(nodes: np.ndarray, edges: np.ndarray, pressure: float, f: np.ndarray) -> None:
    """Add the nodal forces of a pressure [Pa] (positive pushing inward) on boundary edges.

    edges: (k, 2) node pairs oriented counter-clockwise around the body, so that the outward
    normal of edge a -> b is (dy, -dx)/L; each node receives half the edge force -p n L.
    """
    if edges.size == 0:
        return
    d = nodes[edges[:, 1]] - nodes[edges[:, 0]]
    half = -0.5 * pressure * np.stack([d[:, 1], -d[:, 0]], axis=1)  # (k, 2) = -p n L / 2
    for end in (0, 1):
        np.add.at(f, 2 * edges[:, end], half[:, 0])
        np.add.at(f, 2 * edges[:, end] + 1, half[:, 1])


def face_pressure(nodes: np.ndarray, faces: np.ndarray, pressure: float, f: np.ndarray) -> None:
    """Add the consistent nodal forces -p int N_a n dA of a pressure [Pa] on bilinear 3D faces.

    faces: (k, 4) node quadruples whose right-hand normal (x1 - x0) x (x3 - x0) points outward;
    f is the global vector with 3 dofs per node. Exact for planar and warped bilinear faces (2x2 Gauss).
    """
    if faces.size == 0:
        return
    from rockfrac.fem.reference import QUAD4

    x = nodes[faces]  # (k, 4, 3)
    n_q = QUAD4.shape(QUAD4.points)  # (4 qp, 4 nodes)
    dn = QUAD4.shape_gradients(QUAD4.points)  # (4 qp, 4 nodes, 2)
    xi = np.einsum("qa,kai->kqi", dn[:, :, 0], x)  # dx/dxi at the Gauss points
    eta = np.einsum("qa,kai->kqi", dn[:, :, 1], x)
    nda = np.cross(xi, eta)  # (k, qp, 3) = n dA / (dxi deta)
    forces = -pressure * np.einsum("qa,kqi->kai", n_q, nda)  # weights are 1
    for i in range(3):
        np.add.at(f, 3 * faces + i, forces[:, :, i])
