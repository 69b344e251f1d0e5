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
