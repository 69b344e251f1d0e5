"""Nodal integration points of zero-thickness interfaces: one point per (minus, plus) node pair, in
2D (edges) and 3D (triangular or quadrilateral faces)."""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from rockfrac.fem.loads import face_rule, segment_pair_forces


@dataclass
class InterfacePoints:
    """Integration points of the interface cells (paper Sect. 6.2: nodal integration).

    minus, plus: (n_pts,) node indices of each pair; weight: (n_pts,) tributary length [m] (2D) or
    area [m^2] (3D); frame: (n_pts, dim, dim) rotation with rows (t, n) in 2D, (t1, t2, n) in 3D,
    global -> local; x: (n_pts, dim) position [m]; cell: (n_pts,) first interface cell the point
    belongs to (for output); segments: (k, 2 m) the interface cells the points come from (2D: (m0,
    m1, p0, p1)); segment_points: (k, m) the point of each cell's pair (m_j, p_j), -1 where the pair
    is one node (a crack tip or front); segment_x: (k, m, dim) the cells' minus corners [m].
    """

    minus: np.ndarray
    plus: np.ndarray
    weight: np.ndarray
    frame: np.ndarray
    x: np.ndarray
    cell: np.ndarray
    segments: np.ndarray = field(default_factory=lambda: np.zeros((0, 4), dtype=np.int64))
    segment_points: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), dtype=np.int64))
    segment_x: np.ndarray = field(default_factory=lambda: np.zeros((0, 2, 2)))  # (k, 2, 2) ends of each cell [m]
    index: np.ndarray | None = None  # (n_pts,) each point's place among all of the surface's (a subset's)

    def __post_init__(self) -> None:
        if self.index is None:
            self.index = np.arange(self.minus.shape[0])

    @property
    def n(self) -> int:
        return self.minus.shape[0]

    @property
    def dim(self) -> int:
        return self.frame.shape[1]

    @property
    def dofs(self) -> np.ndarray:
        """Displacement dofs (n_pts, 2 dim): (minus x, minus y[, minus z], plus x, plus y[, plus z])."""
        d = self.dim
        return np.concatenate([d * self.minus[:, None] + np.arange(d), d * self.plus[:, None] + np.arange(d)], axis=1)

    def jumps(self, u: np.ndarray) -> np.ndarray:
        """Global-frame jumps u(+) - u(-) at the points, (n_pts, dim) [m] (u: nodal dofs first)."""
        d = self.dim
        un = u[: d * (u.shape[0] // d)].reshape(-1, d)
        return un[self.plus] - un[self.minus]

    def consistent_tractions(self, stress) -> np.ndarray:
        """Global tractions (n_pts, 2) [Pa] of a stress field at the points: the consistent nodal
        forces of sigma . n on the cells, summed per pair and divided by the pair's weight (exactly
        what the bulk on either side transmits, also where sigma varies along the crack)."""
        if self.dim == 3:
            return self._consistent_tractions_3d(stress)
        forces = segment_pair_forces(self.segment_x[:, 0], self.segment_x[:, 1], stress)
        total = np.zeros((self.n, 2))
        for end in range(2):
            hit = self.segment_points[:, end] >= 0
            np.add.at(total, self.segment_points[hit, end], forces[hit, end])
        return total / self.weight[:, None]

    def _consistent_tractions_3d(self, stress) -> np.ndarray:
        shape, x, nda = face_rule(self.segment_x)
        k, nq = x.shape[:2]
        sig = stress(x.reshape(-1, 3)).reshape(k, nq, 6)
        full = sig[..., [0, 3, 5, 3, 1, 4, 5, 4, 2]].reshape(k, nq, 3, 3)
        forces = np.einsum("qa,kqij,kqj->kai", shape, full, nda)  # (k, m, 3)
        total = np.zeros((self.n, 3))
        hit = self.segment_points >= 0
        np.add.at(total, self.segment_points[hit], forces[hit])
        return total / self.weight[:, None]

    def local(self, v: np.ndarray) -> np.ndarray:
        """Rotate global vectors (n_pts, dim) into the local frames."""
        return np.einsum("pij,pj->pi", self.frame, v)

    def from_local(self, v: np.ndarray) -> np.ndarray:
        """Rotate local vectors (n_pts, dim) into the global frame."""
        return np.einsum("pji,pj->pi", self.frame, v)

    def subset(self, keep: np.ndarray) -> InterfacePoints:
        """The points where ``keep`` (a mask) holds, with the weights and frames they have among all
        (one MPI rank's share of a surface); the cells keep the kept points' pairs (-1 elsewhere),
        those left with none are dropped."""
        new = np.full(self.n, -1, dtype=np.int64)
        new[keep] = np.arange(int(np.count_nonzero(keep)))
        seg_points = np.where(self.segment_points >= 0, new[np.maximum(self.segment_points, 0)], -1)
        cells = np.flatnonzero((seg_points >= 0).any(axis=1))
        assert self.index is not None
        return InterfacePoints(self.minus[keep], self.plus[keep], self.weight[keep], self.frame[keep], self.x[keep],
                               self.cell[keep], self.segments[cells], seg_points[cells], self.segment_x[cells],
                               self.index[keep])


def interface_points(nodes: np.ndarray, cells: np.ndarray) -> InterfacePoints:
    """Merge the node pairs of interface cells (m0, m1, p0, p1) into nodal integration points.

    A pair shared by two cells gets the sum of their half-lengths as weight and the
    length-weighted mean of their normals (exactly the cell normal on a straight crack). A pair
    whose minus and plus node are the same node (the tip of a crack ending inside the mesh: the
    node is not split) has no jump and is left out.
    """
    if cells.shape[0] == 0:
        z = np.zeros(0, dtype=np.int64)
        return InterfacePoints(z, z, np.zeros(0), np.zeros((0, 2, 2)), np.zeros((0, 2)), z)
    k = cells.shape[0]
    xm0, xm1 = nodes[cells[:, 0]], nodes[cells[:, 1]]
    seg = xm1 - xm0
    length = np.linalg.norm(seg, axis=1)
    tangent = seg / length[:, None]
    normal = np.stack([-tangent[:, 1], tangent[:, 0]], axis=1)  # (t, n) right-handed
    pairs = np.concatenate([cells[:, [0, 2]], cells[:, [1, 3]]])  # (2 n_cells, 2)
    half = np.concatenate([0.5 * length, 0.5 * length])
    nrm = np.concatenate([normal, normal]) * half[:, None]
    owner = np.concatenate([np.arange(cells.shape[0])] * 2)
    split = pairs[:, 0] != pairs[:, 1]
    pairs, half, nrm, owner = pairs[split], half[split], nrm[split], owner[split]
    uniq, first, inverse = np.unique(pairs, axis=0, return_index=True, return_inverse=True)
    inverse = inverse.ravel()
    segment_points = np.full(2 * k, -1, dtype=np.int64)  # (cell, end) in the order of ``pairs``
    segment_points[np.flatnonzero(split)] = inverse
    weight = np.bincount(inverse, weights=half)
    n_sum = np.stack([np.bincount(inverse, weights=nrm[:, i]) for i in range(2)], axis=1)
    n_unit = n_sum / np.linalg.norm(n_sum, axis=1)[:, None]
    t_unit = np.stack([n_unit[:, 1], -n_unit[:, 0]], axis=1)
    frame = np.stack([t_unit, n_unit], axis=1)
    return InterfacePoints(
        minus=uniq[:, 0].copy(),
        plus=uniq[:, 1].copy(),
        weight=weight,
        frame=frame,
        x=nodes[uniq[:, 0]].copy(),
        cell=owner[first],
        segments=np.asarray(cells, dtype=np.int64),
        segment_points=segment_points.reshape(2, k).T.copy(),
        segment_x=np.stack([xm0[:, :2], xm1[:, :2]], axis=1),
    )



def local_frames_3d(normal: np.ndarray) -> np.ndarray:
    """Frames (n, 3, 3) with rows (t1, t2, n) from unit normals (n, 3): t1 along the strike n x e_z
    (horizontal; e_x where the surface is horizontal), t2 = n x t1 (along the dip), right-handed."""
    strike = np.cross(normal, [0.0, 0.0, 1.0])
    norm = np.linalg.norm(strike, axis=1)
    flat = norm < 1e-8
    t1 = np.where(flat[:, None], [1.0, 0.0, 0.0], strike / np.where(flat, 1.0, norm)[:, None])
    t1 = t1 - np.einsum("pi,pi->p", t1, normal)[:, None] * normal  # exact orthogonality where flat
    t1 /= np.linalg.norm(t1, axis=1)[:, None]
    return np.stack([t1, np.cross(normal, t1), normal], axis=1)


def interface_points_3d(nodes: np.ndarray, cells: np.ndarray) -> InterfacePoints:
    """Merge the node pairs of 3D interface cells (m_0 .. m_{k-1}, p_0 .. p_{k-1}) into nodal
    integration points: weight = sum over the cells of int N_a dA [m^2], normal = the normalised sum
    of int N_a n dA (the face normal on a plane crack). Pairs of one node (a crack front) are left out."""
    m = cells.shape[1] // 2 if cells.size else 3
    if cells.shape[0] == 0:
        z = np.zeros(0, dtype=np.int64)
        return InterfacePoints(z, z, np.zeros(0), np.zeros((0, 3, 3)), np.zeros((0, 3)), z,
                               np.zeros((0, 2 * m), dtype=np.int64), np.zeros((0, m), dtype=np.int64),
                               np.zeros((0, m, 3)))
    k = cells.shape[0]
    xm = nodes[cells[:, :m]]
    shape, _, nda = face_rule(xm)
    node_area = np.einsum("qa,kq->ka", shape, np.linalg.norm(nda, axis=2))  # int N_a dA
    node_normal = np.einsum("qa,kqi->kai", shape, nda)  # (k, m, 3)
    pairs = np.stack([cells[:, :m], cells[:, m:]], axis=2).reshape(-1, 2)
    area, nrm = node_area.ravel(), node_normal.reshape(-1, 3)
    owner = np.repeat(np.arange(k), m)
    split = pairs[:, 0] != pairs[:, 1]
    uniq, first, inverse = np.unique(pairs[split], axis=0, return_index=True, return_inverse=True)
    inverse = inverse.ravel()
    segment_points = np.full(k * m, -1, dtype=np.int64)
    segment_points[np.flatnonzero(split)] = inverse
    weight = np.bincount(inverse, weights=area[split])
    n_sum = np.stack([np.bincount(inverse, weights=nrm[split, i]) for i in range(3)], axis=1)
    normal = n_sum / np.linalg.norm(n_sum, axis=1)[:, None]
    return InterfacePoints(minus=uniq[:, 0].copy(), plus=uniq[:, 1].copy(), weight=weight,
                           frame=local_frames_3d(normal), x=nodes[uniq[:, 0]].copy(), cell=owner[split][first],
                           segments=np.asarray(cells, dtype=np.int64), segment_points=segment_points.reshape(k, m),
                           segment_x=xm)


def _facets(normal: np.ndarray, node: np.ndarray, max_angle: float) -> np.ndarray:
    """Each point's facet: the points of one node joined, pair by pair, where their normals are at most
    2 max_angle apart (either sign), connected components of that graph; (n_pts,) labels. Two edges
    continuing each other through a node form one facet, a crossing of two such lines two."""
    order = np.argsort(node, kind="stable")
    sorted_node = node[order]
    size = np.bincount(np.unique(sorted_node, return_inverse=True)[1].ravel())
    rows, cols = [], []
    for offset in range(1, int(size.max())):  # each point against the ones after it at its node
        a = np.arange(order.size - offset)
        b = a + offset
        same = sorted_node[a] == sorted_node[b]
        a, b = order[a[same]], order[b[same]]
        near = np.abs(np.einsum("pi,pi->p", normal[a], normal[b])) >= np.cos(2.0 * max_angle)
        rows.append(a[near])
        cols.append(b[near])
    n = normal.shape[0]
    r = np.concatenate(rows) if rows else np.zeros(0, dtype=np.int64)
    c = np.concatenate(cols) if cols else np.zeros(0, dtype=np.int64)
    graph = sp.coo_matrix((np.ones(r.size, dtype=np.int8), (r, c)), shape=(n, n))
    return connected_components(graph, directed=False)[1]


def smoothed_normals(points: InterfacePoints, node: np.ndarray, max_angle: float) -> InterfacePoints:
    """The points with a faceted surface's normals smoothed at its vertices (contact's averaged nodal
    normals): the points of one facet at a mesh node (``node``: each point's original node; a facet:
    :func:`_facets`) whose normals all lie within ``max_angle`` [rad] of their weight-averaged mean
    take that mean, each with its own sign. A polygon's vertex or a faceted sheet's node is one facet;
    at a crossing each line (sheet) through the node is one, and the lines are not mixed.

    Where every edge carries a surface, the copies of a node on each side of a polygonal surface are
    tied together by the pairs into the bulk, so the surface's two pairs there see one jump; a
    rigid-plastic pair's jump is its flow, along its own frame, and with the two edges' frames the
    vertex cannot slide. Sharing one frame, the two pairs flow along one direction.
    """
    if points.n == 0:
        return points
    d = points.dim
    normal = points.frame[:, -1]
    group = _facets(normal, np.asarray(node), max_angle)  # labels 0 .. n_facets - 1
    n_groups = int(group.max()) + 1
    order = np.argsort(group, kind="stable")
    first = order[np.searchsorted(group[order], np.arange(n_groups))]  # each facet's first point
    sign = np.where(np.einsum("pi,pi->p", normal, normal[first[group]]) < 0.0, -1.0, 1.0)
    aligned = normal * sign[:, None]
    summed = np.stack([np.bincount(group, weights=points.weight * aligned[:, i], minlength=n_groups)
                       for i in range(d)], axis=1)
    size = np.linalg.norm(summed, axis=1)
    mean = summed / np.where(size > 0.0, size, 1.0)[:, None]
    within = np.einsum("pi,pi->p", aligned, mean[group]) >= np.cos(max_angle)
    smooth_facet = (np.bincount(group, minlength=n_groups) >= 2) & (size > 0.0)
    np.logical_and.at(smooth_facet, group, within)
    smooth = smooth_facet[group]
    if not smooth.any():
        return points
    new = mean[group[smooth]] * sign[smooth, None]
    frame = points.frame.copy()
    frame[smooth] = (np.stack([np.stack([new[:, 1], -new[:, 0]], axis=1), new], axis=1) if d == 2
                     else local_frames_3d(new))
    return replace(points, frame=frame)
