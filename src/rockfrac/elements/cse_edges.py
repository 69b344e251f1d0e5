"""Cohesive surfaces with one point per edge (``[cohesive] points = "edges"``, 2D): the point's jump is
its edge's mean jump, and an elastic moment resists the edge's relative rotation.

rockfrac's nodal points (paper Sect. 6.2) put a point on each (minus, plus) node pair. With surfaces
on every edge a node is split into one copy per cell and its pairs close a ring whose jumps sum to
zero, so rigid-plastic pairs there flow only together: a crack that bends at a node, or meets unyielded
pairs, cannot slide (benchmarks/README.md, "Points per edge"). An edge point constrains the mean jump
(two conditions an edge instead of four), which leaves no ring, and the moment

    E = k L g^2 / 24,   g = n . ((u_p1 - u_m1) - (u_p0 - u_m0))   [J/m]

on the difference g of the edge's end normal jumps (k the set's kn, or its augmentation r for RP; L the
edge's length; the energy of k times the square of a linear normal jump's zero-mean part along the
edge) keeps the yielded edges from turning about their midpoints as hinges. The law, its return, the
viscosity and the RP multipliers are the nodal points' own: each point's rows (minus, plus[,
multiplier]) are mapped onto the edge's four nodes, half to each end.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from rockfrac.elements.base import Evaluation, Measure
from rockfrac.elements.cse_groups import CohesiveEP, CohesiveRP
from rockfrac.elements.interface_points import InterfacePoints
from rockfrac.laws.law3d import Law3D
from rockfrac.laws.traction_law import TractionLaw


def edge_points(nodes: np.ndarray, cells: np.ndarray) -> tuple[InterfacePoints, np.ndarray, np.ndarray]:
    """One point per 2D interface cell (m0, m1, p0, p1): at its midpoint, weight its length [m], frame
    rows (t, n) with t from m0 to m1 (the nodal points' convention); the points' (minus, plus) are the
    cells' first pair, and (m1, p1) come beside."""
    cells = np.asarray(cells, dtype=np.int64)
    xm0, xm1 = nodes[cells[:, 0]], nodes[cells[:, 1]]
    length = np.linalg.norm(xm1 - xm0, axis=1)
    t = (xm1 - xm0) / length[:, None]
    frame = np.stack([t, np.stack([-t[:, 1], t[:, 0]], axis=1)], axis=1)
    k = np.arange(cells.shape[0])
    pts = InterfacePoints(minus=cells[:, 0].copy(), plus=cells[:, 2].copy(), weight=length, frame=frame,
                          x=0.5 * (xm0 + xm1), cell=k, segments=cells, segment_points=np.stack([k, k], axis=1),
                          segment_x=np.stack([xm0, xm1], axis=1))
    return pts, cells[:, 1].copy(), cells[:, 3].copy()


class _OnEdges:
    """What an edge point changes of a nodal point: its jump, its rows on the edge's four nodes (m0,
    m1, p0, p1), the moment on the edge's rotation, and the nodes a separated point parts."""

    per_edge = True
    dim: int
    points: InterfacePoints
    jump_dofs: np.ndarray
    dofs: np.ndarray
    rotation_stiffness: float  # k [Pa/m]
    _second: np.ndarray  # (n, 2): each point's (m1, p1)
    _source: np.ndarray  # the point's row (minus, plus[, multiplier]) of each of the edge's rows
    _share: np.ndarray  # and the share it takes (half for each end's node, all of a multiplier's)
    _share2: np.ndarray  # the shares' outer product, for the blocks
    _rotation: np.ndarray  # (n, 4 dim): g = rotation . u over (m0, m1, p0, p1)

    def _on_edges(self, m1: np.ndarray, p1: np.ndarray, multipliers: bool) -> None:
        d = self.dim
        ar = np.arange(d)
        jd = self.points.dofs
        self._second = np.stack([m1, p1], axis=1)
        self.jump_dofs = np.concatenate([jd[:, :d], d * m1[:, None] + ar, jd[:, d:], d * p1[:, None] + ar], axis=1)
        self.dofs = self.jump_dofs
        # each row of the edge's (m0, m1, p0, p1[, multiplier]): the point's row it takes, and its share
        self._source = np.concatenate([ar, ar, d + ar, d + ar] + ([2 * d + ar] if multipliers else []))
        self._share = np.concatenate([np.full(4 * d, 0.5)] + ([np.ones(d)] if multipliers else []))
        self._share2 = np.outer(self._share, self._share)
        n = self.points.frame[:, 1]
        self._rotation = np.concatenate([n, -n, -n, n], axis=1)

    def jumps(self, u: np.ndarray) -> np.ndarray:
        """Global-frame mean jumps of the edges (n_pts, dim) [m]."""
        d, j = self.dim, self.jump_dofs
        return 0.5 * (u[j[:, 2 * d:3 * d]] - u[j[:, :d]] + u[j[:, 3 * d:4 * d]] - u[j[:, d:2 * d]])

    def rotation_jumps(self, u: np.ndarray) -> np.ndarray:
        """g, the difference of each edge's end normal jumps (n_pts,) [m]."""
        return np.einsum("pi,pi->p", self._rotation, u[self.jump_dofs[:, :4 * self.dim]])

    def moment_energy(self, u: np.ndarray) -> float:
        """The moments' elastic energy sum k L g^2 / 24 [J/m]."""
        return float(np.sum(self.rotation_stiffness * self.points.weight * self.rotation_jumps(u) ** 2) / 24.0)

    def elastic_energy(self, u: np.ndarray) -> float:
        """The law's stored energy at the points and the moments' [J/m]."""
        return super().elastic_energy(u) + self.moment_energy(u)  # type: ignore[misc]

    def _edge_rows(self, ev: Evaluation, u: np.ndarray) -> Evaluation:
        src, c, n4 = self._source, self._rotation, 4 * self.dim
        fe = ev.fe[:, src] * self._share
        ke = ev.ke[:, src[:, None], src[None, :]] * self._share2
        k = self.rotation_stiffness * self.points.weight / 12.0
        fe[:, :n4] += (k * self.rotation_jumps(u))[:, None] * c
        ke[:, :n4, :n4] += k[:, None, None] * c[:, :, None] * c[:, None, :]
        return replace(ev, fe=fe, ke=ke)

    def jump_measure(self, n_dofs: int) -> Measure:
        """The nodal points' path measure on the edges' mean jumps."""
        pts, d = self.points, self.dim
        m = self.flow_directions() * (pts.weight / pts.weight.sum())[:, None]  # type: ignore[attr-defined]
        grad = np.zeros(n_dofs)
        for block, sign in ((0, -1.0), (1, -1.0), (2, 1.0), (3, 1.0)):
            np.add.at(grad, self.jump_dofs[:, block * d:(block + 1) * d], 0.5 * sign * m)

        def measure(u: np.ndarray) -> tuple[float, np.ndarray]:
            return float(np.sum(m * self.jumps(u))), grad

        return measure

    def evaluate(self, u: np.ndarray, u_n: np.ndarray) -> Evaluation:
        """The nodal points' evaluation at the edges' mean jumps, on the edges' nodes, with the moments."""
        return self._edge_rows(super().evaluate(u, u_n), u)  # type: ignore[misc]

    def separated(self, fraction: float) -> tuple[np.ndarray, float]:
        """The separated edges' node pairs (k, 2), both of each (a separated edge parts its whole length),
        and their length [m]."""
        hit = self.law.separated(self.state, fraction)  # type: ignore[attr-defined]
        first = np.stack([self.points.minus[hit], self.points.plus[hit]], axis=1)
        return np.concatenate([first, self._second[hit]]), float(self.points.weight[hit].sum())


class EdgeEP(_OnEdges, CohesiveEP):
    """EP surfaces with one point per edge (the moment's k: the law's kn)."""

    def __init__(self, points: InterfacePoints, m1: np.ndarray, p1: np.ndarray, law: TractionLaw | Law3D, *,
                 name: str = "cohesive", viscosity: float = 0.0):
        super().__init__(points, law, name=name, viscosity=viscosity)
        assert law.kn is not None
        self.rotation_stiffness = float(law.kn)
        self._on_edges(m1, p1, multipliers=False)


class EdgeRP(_OnEdges, CohesiveRP):
    """RP surfaces with one point per edge (the moment's k: the augmentation r). No junction term: an
    edge point closes no ring of pairs round a node."""

    def __init__(self, points: InterfacePoints, m1: np.ndarray, p1: np.ndarray, law: TractionLaw | Law3D,
                 augmentation: float, *, name: str = "cohesive", viscosity: float = 0.0):
        super().__init__(points, law, augmentation, junction=np.zeros(points.n, dtype=bool), name=name,
                         viscosity=viscosity)
        self.rotation_stiffness = float(augmentation)
        self._on_edges(m1, p1, multipliers=True)

    def redundant_extras(self, dirichlet: np.ndarray) -> np.ndarray:
        """Multiplier dofs whose mean jump the Dirichlet conditions hold: all four nodes held in that component."""
        d = self.dim
        held = np.isin(self.jump_dofs, dirichlet)
        out = [self.lam_dofs[np.all(held[:, a::d], axis=1), a] for a in range(d)]
        return np.concatenate(out).astype(np.int64)
