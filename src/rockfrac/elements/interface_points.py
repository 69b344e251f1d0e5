"""Nodal integration points of zero-thickness interfaces: one point per (minus, plus) node pair."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from rockfrac.fem.loads import segment_pair_forces


@dataclass
class InterfacePoints:
    """Integration points of the interface cells (paper Sect. 6.2: nodal integration).

    minus, plus: (n_pts,) node indices of each pair; weight: (n_pts,) tributary length [m];
    frame: (n_pts, 2, 2) rotation with rows (t, n), global -> local; x: (n_pts, 2) position [m];
    cell: (n_pts,) first interface cell the point belongs to (for output); segments: (k, 4) the
    interface cells (m0, m1, p0, p1) the points come from; segment_points: (k, 2) the point of each
    cell's pair (m0, p0) and (m1, p1), -1 where the pair is one node (a crack tip).
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

    @property
    def n(self) -> int:
        return self.minus.shape[0]

    @property
    def dofs(self) -> np.ndarray:
        """Displacement dofs (n_pts, 4): (minus x, minus y, plus x, plus y)."""
        return np.stack([2 * self.minus, 2 * self.minus + 1, 2 * self.plus, 2 * self.plus + 1], axis=1)

    def jumps(self, u: np.ndarray) -> np.ndarray:
        """Global-frame jumps u(+) - u(-) at the points, (n_pts, 2) [m]."""
        u2 = u[: 2 * (u.shape[0] // 2)].reshape(-1, 2)
        return u2[self.plus] - u2[self.minus]

    def consistent_tractions(self, stress) -> np.ndarray:
        """Global tractions (n_pts, 2) [Pa] of a stress field at the points: the consistent nodal
        forces of sigma . n on the cells, summed per pair and divided by the pair's weight (exactly
        what the bulk on either side transmits, also where sigma varies along the crack)."""
        forces = segment_pair_forces(self.segment_x[:, 0], self.segment_x[:, 1], stress)
        total = np.zeros((self.n, 2))
        for end in range(2):
            hit = self.segment_points[:, end] >= 0
            np.add.at(total, self.segment_points[hit, end], forces[hit, end])
        return total / self.weight[:, None]

    def local(self, v: np.ndarray) -> np.ndarray:
        """Rotate global vectors (n_pts, 2) into the local (t, n) frames."""
        return np.einsum("pij,pj->pi", self.frame, v)


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

