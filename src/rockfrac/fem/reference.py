"""Reference elements: linear triangle (T3, 1 point), bilinear quadrilateral (Q4, 2x2 Gauss),
linear tetrahedron (Tet4, 1 point) and trilinear hexahedron (Hex8, 2x2x2).

Node orders follow VTK: T3 counter-clockwise from (0, 0); Q4 counter-clockwise from (-1, -1);
Tet4 (0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1) (the fourth node on the side where the first
three turn counter-clockwise); Hex8 the bottom face (zeta = -1) counter-clockwise from
(-1, -1, -1), then the top face above it. Tensor-product shape functions N_a = prod_i (1 + xi_a,i
xi_i) / 2^dim; simplices: N_0 = 1 - sum_i xi_i, N_a = xi_(a-1).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

_G = 1.0 / np.sqrt(3.0)


@dataclass(frozen=True)
class ReferenceElement:
    """Nodes (n_nodes, dim) and Gauss points (n_qp, dim), weights (n_qp,) of an isoparametric element."""

    name: str
    nodes: np.ndarray
    points: np.ndarray
    weights: np.ndarray

    @property
    def dim(self) -> int:
        return self.nodes.shape[1]

    @property
    def simplex(self) -> bool:
        """A linear simplex (tri3, tet4): constant gradients, one Gauss point."""
        return self.name in ("tri3", "tet4")

    @property
    def n_nodes(self) -> int:
        return self.nodes.shape[0]

    def shape(self, xi: np.ndarray) -> np.ndarray:
        """N_a at points xi (n, dim): (n, n_nodes)."""
        xi = np.atleast_2d(xi)
        if self.simplex:
            return np.column_stack([1.0 - xi.sum(axis=1), xi])
        return np.prod(0.5 * (1.0 + xi[:, None, :] * self.nodes[None, :, :]), axis=2)

    def shape_gradients(self, xi: np.ndarray) -> np.ndarray:
        """dN_a/dxi_j at points xi (n, dim): (n, n_nodes, dim)."""
        xi = np.atleast_2d(xi)
        if self.simplex:
            d = np.vstack([-np.ones(self.dim), np.eye(self.dim)])
            return np.broadcast_to(d, (xi.shape[0], self.dim + 1, self.dim)).copy()
        f = 0.5 * (1.0 + xi[:, None, :] * self.nodes[None, :, :])  # (n, a, dim)
        out = np.empty(f.shape)
        for j in range(self.dim):
            others = np.prod(np.delete(f, j, axis=2), axis=2)
            out[:, :, j] = 0.5 * self.nodes[None, :, j] * others
        return out


QUAD4 = ReferenceElement(
    "quad4",
    nodes=np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]]),
    points=np.array([[-_G, -_G], [_G, -_G], [_G, _G], [-_G, _G]]),
    weights=np.ones(4),
)

_H8 = np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]])
HEX8 = ReferenceElement(
    "hex8",
    nodes=np.vstack([np.column_stack([_H8, -np.ones(4)]), np.column_stack([_H8, np.ones(4)])]),
    points=np.vstack([np.column_stack([_G * _H8, -_G * np.ones(4)]), np.column_stack([_G * _H8, _G * np.ones(4)])]),
    weights=np.ones(8),
)

TRI3 = ReferenceElement(
    "tri3",
    nodes=np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]),
    points=np.array([[1.0 / 3.0, 1.0 / 3.0]]),
    weights=np.array([0.5]),
)

TET4 = ReferenceElement(
    "tet4",
    nodes=np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]),
    points=np.array([[0.25, 0.25, 0.25]]),
    weights=np.array([1.0 / 6.0]),
)

#: the three-point rule of a triangle (exact for quadratics): points on the reference T3, weights
TRIANGLE_RULE = (np.array([[1.0 / 6.0, 1.0 / 6.0], [2.0 / 3.0, 1.0 / 6.0], [1.0 / 6.0, 2.0 / 3.0]]),
                 np.full(3, 1.0 / 6.0))

ELEMENTS = {"tri3": TRI3, "quad4": QUAD4, "tet4": TET4, "hex8": HEX8}
