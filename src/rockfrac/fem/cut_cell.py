"""A 2D cell cut by a straight crack: its two sides' quadrature and the crack's points (nodal
embedded cracks, rockfrac.elements.ede_nodal).

Each side of the line is a convex polygon (the cell clipped by the line), fanned into triangles
that carry the three-point rule (exact for quadratics in x): every point gets its reference
coordinates in the cell (the isoparametric map inverted by Newton for a quadrilateral), its shape
gradients and its weight (the triangle's area share) [m^2 per unit thickness]. The crack's points
are the two ends of its chord through the cell and its middle, with Simpson's weights (1, 4, 1)/6
of the chord's length: Newton-Cotes along the crack (as for cohesive surfaces: no traction
oscillations under a stiff penalty), exact for the quadratic shape functions of a quadrilateral
along a line, so that a uniform traction balances a uniform stress (the patch test); the ends come
with the cell edge each lies on.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rockfrac.fem.planes import EDGES, plane_polygons
from rockfrac.fem.reference import TRIANGLE_RULE, ReferenceElement


@dataclass
class CutCell:
    """Quadrature of a cut cell: side points (xi (m, 2), x (m, 2) [m], weights (m,) [m^2], side (m,) 1
    on the + side (where (x - point) . n > 0), 0 on the other), the crack's points (its two ends and
    its middle: xi (3, 2), x (3, 2) [m], weights (3,) [m]) and the cell edge each end lies on (2,),
    edge k from node k to node k + 1."""

    xi: np.ndarray
    x: np.ndarray
    weights: np.ndarray
    side: np.ndarray
    crack_xi: np.ndarray
    crack_x: np.ndarray
    crack_weights: np.ndarray
    crack_edges: np.ndarray


def clip(polygon: np.ndarray, point: np.ndarray, normal: np.ndarray, sign: float) -> np.ndarray:
    """The part of a convex polygon (k, 2), counter-clockwise, where sign (x - point) . n >= 0."""
    d = sign * ((polygon - point) @ normal)
    out = []
    k = polygon.shape[0]
    for a in range(k):
        b = (a + 1) % k
        if d[a] >= 0.0:
            out.append(polygon[a])
        if min(d[a], d[b]) < 0.0 < max(d[a], d[b]):
            out.append(polygon[a] + d[a] / (d[a] - d[b]) * (polygon[b] - polygon[a]))
    return np.array(out)


def inverse_map(ref: ReferenceElement, xe: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Reference coordinates (m, 2) of physical points x (m, 2) [m] in the cell with nodes xe (k, 2)."""
    if ref.simplex:
        jac = (xe[1:] - xe[0]).T  # x = x0 + J xi
        return np.linalg.solve(jac, (x - xe[0]).T).T
    xi = np.zeros_like(x)
    for _ in range(50):
        n = ref.shape(xi)
        r = n @ xe - x
        dn = ref.shape_gradients(xi)
        jac = np.einsum("pai,aj->pji", dn, xe)  # dx_j / dxi_i
        step = np.linalg.solve(jac, r[..., None])[..., 0]
        xi -= step
        if np.abs(step).max() <= 1e-14:
            break
    return xi


def cut_cell(ref: ReferenceElement, xe: np.ndarray, point: np.ndarray, normal: np.ndarray) -> CutCell:
    """The quadrature of the cell with nodes xe (k, 2) [m] (counter-clockwise) cut by the line through
    ``point`` with unit ``normal`` (module doc)."""
    rule_xi, rule_w = TRIANGLE_RULE
    xs, ws, sides = [], [], []
    for side, sign in ((1, 1.0), (0, -1.0)):
        poly = clip(xe, point, normal, sign)
        for a in range(1, poly.shape[0] - 1):
            v0, v1, v2 = poly[0], poly[a], poly[a + 1]
            area2 = (v1[0] - v0[0]) * (v2[1] - v0[1]) - (v1[1] - v0[1]) * (v2[0] - v0[0])
            if area2 <= 0.0:
                continue  # a degenerate fan triangle (a vertex on the line)
            xs.append(v0 + rule_xi[:, :1] * (v1 - v0) + rule_xi[:, 1:] * (v2 - v0))
            ws.append(rule_w * area2)
            sides.append(np.full(rule_w.size, side))
    x = np.vstack(xs)
    t = np.array([normal[1], -normal[0]])
    ends, edges = [], []
    k = xe.shape[0]
    d = (xe - point) @ normal
    for a in range(k):
        b = (a + 1) % k
        if (d[a] > 0.0) != (d[b] > 0.0):
            ends.append(xe[a] + d[a] / (d[a] - d[b]) * (xe[b] - xe[a]))
            edges.append(a)
    if len(ends) != 2:
        raise ValueError(f"the line does not cut the cell into two sides (it crosses {len(ends)} edges)")
    ends_x = np.array(ends)
    order = np.argsort(ends_x @ t)
    ends_x, edge_of = ends_x[order], np.array(edges)[order]
    length = float(np.linalg.norm(ends_x[1] - ends_x[0]))
    crack_x = np.array([ends_x[0], 0.5 * (ends_x[0] + ends_x[1]), ends_x[1]])
    return CutCell(inverse_map(ref, xe, x), x, np.concatenate(ws), np.concatenate(sides),
                   inverse_map(ref, xe, crack_x), crack_x, np.array([1.0, 4.0, 1.0]) * length / 6.0, edge_of)


def physical_gradients(ref: ReferenceElement, xe: np.ndarray, xi: np.ndarray) -> np.ndarray:
    """dN_a/dx (m, n_nodes, 2) [1/m] at reference points xi (m, 2) of the cell with nodes xe."""
    dn = ref.shape_gradients(xi)  # (m, a, i)
    jac = np.einsum("pai,aj->pij", dn, xe)  # dx_j/dxi_i, (m, i, j)
    return np.linalg.solve(jac[:, None, :, :], dn[..., None])[..., 0]


# -- a 3D cell (tet4, hex8) cut by a plane ----------------------------------------------------------

#: the faces of the reference cells (node lists, Gmsh/VTK order), each once
FACES: dict[str, list[tuple[int, ...]]] = {
    "tet4": [(0, 2, 1), (0, 1, 3), (1, 2, 3), (0, 3, 2)],
    "hex8": [(0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7)],
}


def _tet_orbit(a: float) -> np.ndarray:
    """The four points (barycentric) of a tetrahedron's orbit (1 - 3a, a, a, a)."""
    return np.array([[1 - 3 * a, a, a, a], [a, 1 - 3 * a, a, a], [a, a, 1 - 3 * a, a], [a, a, a, 1 - 3 * a]])


#: an eight-point rule of a tetrahedron, degree 3, positive weights (fractions of its volume): two
#: orbits of four points, solved from the moments of degree 2 and 3 (tests/test_nodal_3d.py checks
#: every monomial up to degree 3). A trilinear cell's gradients against a linear stress, or its shape
#: functions against a uniform body force, are of degree 3.
_TA, _TB, _TW = 0.10190354747154126, 0.32771827152905775, 0.10161867104040027
TET_RULE_3 = (np.vstack([_tet_orbit(_TA), _tet_orbit(_TB)]), np.r_[np.full(4, _TW), np.full(4, 0.25 - _TW)])
_A, _B = 0.445948490915965, 0.091576213509771  # the six-point rule of a triangle (degree 4)
TRIANGLE_RULE_6 = (np.array([[_A, _A, 1 - 2 * _A], [_A, 1 - 2 * _A, _A], [1 - 2 * _A, _A, _A],
                             [_B, _B, 1 - 2 * _B], [_B, 1 - 2 * _B, _B], [1 - 2 * _B, _B, _B]]),
                   np.array([0.223381589678011] * 3 + [0.109951743655322] * 3))
TRIANGLE_RULE_3 = (np.array([[2 / 3, 1 / 6, 1 / 6], [1 / 6, 2 / 3, 1 / 6], [1 / 6, 1 / 6, 2 / 3]]), np.full(3, 1 / 3))


def _side_polyhedron(xe: np.ndarray, edges: np.ndarray, d: np.ndarray, sign: float) -> np.ndarray:
    """The corners (m, 3) of the part of a convex cell where sign d >= 0: its nodes there and where its
    edges cross the plane (d the nodes' signed distances)."""
    keep = [xe[a] for a in range(xe.shape[0]) if sign * d[a] >= 0.0]
    for a, b in edges:
        if min(d[a], d[b]) < 0.0 < max(d[a], d[b]):
            keep.append(xe[a] + d[a] / (d[a] - d[b]) * (xe[b] - xe[a]))
    return np.array(keep)


def _tetrahedra(corners: np.ndarray) -> np.ndarray:
    """A convex polyhedron given by its corners (m, 3) as tetrahedra (t, 4, 3): its hull's triangles
    fanned from its centroid."""
    from scipy.spatial import ConvexHull

    centre = corners.mean(axis=0)
    hull = ConvexHull(corners)
    tets = np.array([[centre, *corners[s]] for s in hull.simplices])
    vol = np.einsum("ti,ti->t", np.cross(tets[:, 1] - tets[:, 0], tets[:, 2] - tets[:, 0]), tets[:, 3] - tets[:, 0])
    return tets[np.abs(vol) > 1e-14 * np.abs(vol).max()]


def cut_cell_3d(ref: ReferenceElement, xe: np.ndarray, point: np.ndarray, normal: np.ndarray) -> CutCell:
    """The quadrature of a convex 3D cell with nodes xe (k, 3) [m] cut by the plane through ``point``
    with unit ``normal``: each side's points (a tetrahedron's sides strain uniformly: one point each,
    at its centroid with its volume; a hexahedron's: the side's hull fanned into tetrahedra, eight
    points each, of degree 3) and the crack's polygon fanned into triangles (three points each for a tetrahedron,
    whose shape functions are linear on it; six, degree 4, for a hexahedron). ``crack_edges`` here
    lists the faces of the cell (indices into FACES) the crack crosses."""
    edges = EDGES[ref.name]
    d = (xe - point) @ normal
    xs, ws, sides = [], [], []
    for side, sign in ((1, 1.0), (0, -1.0)):
        tets = _tetrahedra(_side_polyhedron(xe, edges, d, sign))
        vol = np.abs(np.einsum("ti,ti->t", np.cross(tets[:, 1] - tets[:, 0], tets[:, 2] - tets[:, 0]),
                               tets[:, 3] - tets[:, 0])) / 6.0
        if ref.simplex:
            centres = np.einsum("t,tci->i", vol, tets) / (4.0 * vol.sum())
            xs.append(centres[None, :])
            ws.append(np.array([vol.sum()]))
            sides.append(np.array([side]))
        else:
            rule, rule_w = TET_RULE_3
            xs.append(np.einsum("qc,tci->tqi", rule, tets).reshape(-1, 3))
            ws.append((vol[:, None] * rule_w[None, :]).ravel())
            sides.append(np.full(rule_w.size * tets.shape[0], side))
    x = np.vstack(xs)
    poly = plane_polygons(xe[None], edges, np.asarray(point, float)[None], np.asarray(normal, float)[None])[0][0]
    poly = poly[np.isfinite(poly).all(axis=1)]
    rule, rule_w = TRIANGLE_RULE_3 if ref.simplex else TRIANGLE_RULE_6
    centre = poly.mean(axis=0)
    cx, cw = [], []
    for a in range(poly.shape[0]):
        tri = np.array([centre, poly[a], poly[(a + 1) % poly.shape[0]]])
        area = 0.5 * np.linalg.norm(np.cross(tri[1] - tri[0], tri[2] - tri[0]))
        cx.append(rule @ tri)
        cw.append(rule_w * area)
    crack_x = np.vstack(cx)
    crossed = np.array([k for k, face in enumerate(FACES[ref.name])
                        if d[list(face)].min() < 0.0 < d[list(face)].max()])
    return CutCell(inverse_map(ref, xe, x), x, np.concatenate(ws), np.concatenate(sides),
                   inverse_map(ref, xe, crack_x), crack_x, np.concatenate(cw), crossed)


def clip_by(points: np.ndarray, d: np.ndarray, sign: float) -> np.ndarray:
    """The part where sign d >= 0 of a segment (2, dim) or a polygon (m, dim) (its corners in order),
    d the corners' signed distances to a line or plane."""
    if points.shape[0] == 2:
        keep = [points[a] for a in range(2) if sign * d[a] >= 0.0]
        if min(d) < 0.0 < max(d):
            keep.insert(1 if sign * d[0] >= 0.0 else 0, points[0] + d[0] / (d[0] - d[1]) * (points[1] - points[0]))
        return np.array(keep)
    out = []
    k = points.shape[0]
    for a in range(k):
        b = (a + 1) % k
        if sign * d[a] >= 0.0:
            out.append(points[a])
        if min(d[a], d[b]) < 0.0 < max(d[a], d[b]):
            out.append(points[a] + d[a] / (d[a] - d[b]) * (points[b] - points[a]))
    return np.array(out)
