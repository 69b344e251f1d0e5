"""Cell geometry a mesh needs without finite elements: the cell types, their corner Jacobians (to
check and orient cells) and a straight surface clipped to a 2D cell."""

from __future__ import annotations

import numpy as np

#: cell type -> (dimension, corner coordinates in the reference cell, VTK node order)
CELL_TYPES: dict[str, tuple[int, np.ndarray]] = {
    "tri3": (2, np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])),
    "quad4": (2, np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]])),
    "tet4": (3, np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])),
    "hex8": (3, np.array([[-1.0, -1.0, -1.0], [1.0, -1.0, -1.0], [1.0, 1.0, -1.0], [-1.0, 1.0, -1.0],
                          [-1.0, -1.0, 1.0], [1.0, -1.0, 1.0], [1.0, 1.0, 1.0], [-1.0, 1.0, 1.0]])),
}


def _corner_neighbours(corners: np.ndarray) -> np.ndarray:
    """For each corner and reference direction i: the corner across the edge along i (tensor cells)."""
    k, dim = corners.shape
    out = np.empty((k, dim), dtype=np.int64)
    for a in range(k):
        for i in range(dim):
            other = corners[a].copy()
            other[i] = -other[i]
            out[a, i] = int(np.flatnonzero(np.all(corners == other, axis=1))[0])
    return out


def corner_jacobians(nodes: np.ndarray, cells: np.ndarray, cell_type: str) -> np.ndarray:
    """det J (up to a positive factor) at every corner of every cell, (n_cells, n_corners): the
    signed area (volume) spanned by the cell's edges leaving each corner in the reference directions.
    All positive: a valid, counter-clockwise (right-handed) cell; all negative: valid but mirrored."""
    dim, corners = CELL_TYPES[cell_type]
    x = nodes[cells][..., :dim]
    if cell_type == "tri3":
        e1, e2 = x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]
        det = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
        return np.repeat(det[:, None], 3, axis=1)
    if cell_type == "tet4":
        e = x[:, 1:] - x[:, :1]  # (n, 3 edges, 3)
        det = np.einsum("ki,ki->k", np.cross(e[:, 0], e[:, 1]), e[:, 2])
        return np.repeat(det[:, None], 4, axis=1)
    nb = _corner_neighbours(corners)
    out = np.empty(cells.shape)
    for a in range(corners.shape[0]):
        cols = [np.sign(corners[nb[a, i], i] - corners[a, i]) * (x[:, nb[a, i]] - x[:, a]) for i in range(dim)]
        out[:, a] = np.linalg.det(np.stack(cols, axis=-1))
    return out


def surface_segment(xe: np.ndarray, normal: np.ndarray, point: np.ndarray | None = None) -> np.ndarray:
    """End points (2, 2) of the line through ``point`` (default: the centroid) with this normal,
    clipped to the convex cell with nodes xe (k, 2)."""
    xc = xe.mean(axis=0) if point is None else np.asarray(point, dtype=float)
    t = np.array([normal[1], -normal[0]])
    hits = []
    k = xe.shape[0]
    for a in range(k):
        p, q = xe[a], xe[(a + 1) % k]
        mat = np.column_stack([t, p - q])
        if abs(np.linalg.det(mat)) < 1e-14 * np.abs(xe).max() ** 2:
            continue
        s, lam = np.linalg.solve(mat, p - xc)
        if -1e-12 <= lam <= 1 + 1e-12:
            hits.append(s)
    return xc + np.outer([min(hits), max(hits)], t)
