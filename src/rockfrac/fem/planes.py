"""Planes through 3D cells (embedded cracks): the polygon where a cell's surface cuts it, its area, and the
cells a plane given in advance crosses. Coordinates in m; a cell is convex (hex8 with planar faces,
tet4), so a plane cuts it in one convex polygon of 3 to 6 vertices, each on one of its edges."""

from __future__ import annotations

import numpy as np

# the edges of the reference cells (Gmsh/VTK node order)
EDGES = {
    "hex8": np.array([[0, 1], [1, 2], [2, 3], [3, 0], [4, 5], [5, 6], [6, 7], [7, 4],
                      [0, 4], [1, 5], [2, 6], [3, 7]]),
    "tet4": np.array([[0, 1], [1, 2], [2, 0], [0, 3], [1, 3], [2, 3]]),
}
MAX_VERTICES = 6


def plane_polygons(x: np.ndarray, edges: np.ndarray, point: np.ndarray, normal: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Where the planes through ``point`` (k, 3) with ``normal`` (k, 3) cut the cells x (k, m, 3).

    A node on the plane counts as below it (the + side is (x - point) . n > 0, as the cells' active
    nodes). Returns the vertices (k, 6, 3), ordered around the polygon and NaN-padded, and for each the
    edge's end nodes (k, 6, 2) (-1 padded) and its place s along the edge (k, 6): the vertex is
    (1 - s) x_a + s x_b, so a field linear along the edges (every node-based field of hex8 and tet4)
    takes (1 - s) v_a + s v_b there.
    """
    k = x.shape[0]
    d = np.einsum("kmi,ki->km", x - point[:, None, :], normal)  # signed distances of the nodes
    a, b = edges[:, 0], edges[:, 1]
    da, db = d[:, a], d[:, b]  # (k, E)
    cross = (da > 0.0) != (db > 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        s = np.where(cross, da / (da - db), np.nan)
    verts = x[:, a] + s[..., None] * (x[:, b] - x[:, a])  # (k, E, 3), NaN where not crossed
    # the same vertex from two edges (a node on the plane): keep one
    same = np.linalg.norm(verts[:, :, None] - verts[:, None, :], axis=-1)
    scale = np.ptp(x, axis=1).max(axis=1)[:, None, None]
    earlier = np.tril(np.ones((edges.shape[0], edges.shape[0]), dtype=bool), -1)[None]
    duplicate = ((same <= 1e-12 * scale) & earlier).any(axis=2)
    keep = cross & ~duplicate
    centre = np.nanmean(np.where(keep[..., None], verts, np.nan), axis=1)  # (k, 3)
    u = in_plane_direction(normal)
    v = np.cross(normal, u)
    rel = verts - centre[:, None, :]
    angle = np.arctan2(np.einsum("kei,ki->ke", rel, v), np.einsum("kei,ki->ke", rel, u))
    angle = np.where(keep, angle, np.inf)
    order = np.argsort(angle, axis=1)[:, :MAX_VERTICES]
    taken = np.take_along_axis(keep, order, axis=1)
    rows = np.arange(k)[:, None]
    out = np.where(taken[..., None], verts[rows, order], np.nan)
    ends = np.where(taken[..., None], edges[order], -1)
    where = np.where(taken, s[rows, order], np.nan)
    return out, ends, where


def in_plane_direction(normal: np.ndarray) -> np.ndarray:
    """A unit vector normal to each normal (k, 3)."""
    helper = np.where(np.abs(normal[:, :1]) < 0.9, np.array([[1.0, 0.0, 0.0]]), np.array([[0.0, 1.0, 0.0]]))
    u = np.cross(normal, helper)
    return u / np.linalg.norm(u, axis=1, keepdims=True)


def polygon_areas(verts: np.ndarray) -> np.ndarray:
    """Areas (k,) [m^2] of convex polygons (k, 6, 3), NaN-padded after their last vertex."""
    ok = np.isfinite(verts).all(axis=2)
    first = verts[:, :1]
    rel = np.where(ok[..., None], verts - first, 0.0)
    nxt = np.roll(rel, -1, axis=1)
    nxt_ok = np.roll(ok, -1, axis=1)
    fan = np.cross(rel, np.where(nxt_ok[..., None], nxt, 0.0))
    return 0.5 * np.linalg.norm(fan.sum(axis=1), axis=1)


def fan_triangles(verts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The polygons (k, 6, 3) as fans of triangles: (polygon index (t,), vertex indices (t, 3)) with
    vertex index = 6 * polygon + corner."""
    fans = np.maximum(np.isfinite(verts).all(axis=2).sum(axis=1) - 2, 0)  # triangles per polygon
    poly = np.repeat(np.arange(verts.shape[0]), fans)
    corner = np.arange(poly.size) - np.repeat(np.cumsum(fans) - fans, fans) + 1
    base = MAX_VERTICES * poly
    return poly, np.column_stack([base, base + corner, base + corner + 1])
