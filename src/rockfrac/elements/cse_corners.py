"""Cohesive surfaces integrated per interface cell at its corners (``[cohesive] points = "corners"``).

Each interface cell (a 2D edge m0 m1 p0 p1, a 3D triangle or quadrilateral face) carries its own
integration points at its corners: the node pairs (m_a, p_a), with the cell's own frame and the
corner's share of its size (half the length of an edge; int N_a dA of a face). That is the nodal
rule of the paper (Sect. 6.2) applied cell by cell, so EP corner points are the nodal points with a
point per cell at each node pair.

RP corner points share one multiplier per cell (global-frame traction [Pa], dim components): the
cell's rows sum w_a (T_a - lambda), so at convergence lambda is the cell's mean traction and the
cell's mean jump is rigid until it yields (paper eq. 32-34), while each corner's deviation from it,
T_a - lambda = r e_a, is elastic with the augmentation r as stiffness and carried from step to step.
With every edge split, the copies of a node are tied in rings by nodal RP pairs (two constraints per
pair, their multipliers statically indeterminate); a cell's dim constraints close no ring. Each
corner keeps its own law state, so an edge rocked open at one end yields and softens there, as a
node pair does.

On MPI ranks every corner of a cell is on the cell's rank (its multipliers too), so the cell means are
the rank's own; a node pair shared by cells of two ranks is separated only where neither holds it
(:meth:`_AtCorners.holding`, which the history's fragment count subtracts).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import structural_rank

from rockfrac.elements.base import Evaluation
from rockfrac.elements.cse_facets import facet_points
from rockfrac.elements.cse_groups import CohesiveEP, CohesiveRP
from rockfrac.elements.interface_points import InterfacePoints
from rockfrac.fem.loads import face_rule
from rockfrac.laws.law3d import Law3D
from rockfrac.laws.traction_law import TractionLaw


def corner_points(nodes: np.ndarray, cells: np.ndarray) -> InterfacePoints:
    """The corner points of interface cells (k, 2 m) (m_0 .. m_{m-1}, p_0 .. p_{m-1}): point m c + a is
    cell c's pair (m_a, p_a), weight the corner's share of the cell's length [m] or area [m^2], frame
    the cell's (rows (t, n), (t1, t2, n); :func:`facet_points`), x the minus corner [m]."""
    cells = np.asarray(cells, dtype=np.int64)
    k, m = cells.shape[0], cells.shape[1] // 2
    facets, _ = facet_points(nodes, cells)
    if nodes.shape[1] == 2:
        weight = np.repeat(0.5 * facets.weight, m)
    else:
        shape, _, nda = face_rule(nodes[cells[:, :m]])
        weight = np.einsum("qa,kq->ka", shape, np.linalg.norm(nda, axis=2)).ravel()
    return InterfacePoints(minus=cells[:, :m].ravel(), plus=cells[:, m:].ravel(), weight=weight,
                           frame=np.repeat(facets.frame, m, axis=0), x=nodes[cells[:, :m]].reshape(k * m, -1),
                           cell=np.repeat(np.arange(k), m), segments=cells,
                           segment_points=np.arange(k * m).reshape(k, m), segment_x=facets.segment_x)


def undetermined_cells(cells: np.ndarray) -> tuple[int, int]:
    """How many of the interface cells' (k, 2 m) multipliers, one set per cell fixing the mean jump of its
    corners' node pairs, those pairs cannot determine: k less the structural rank of the cells x pairs
    incidence (a pair whose two nodes are one, at a crack's tip, has no jump); and how many split pairs
    there are. Zero on a line of edges or a surface of quadrilaterals; a surface of triangles has about
    two faces per node (the P1-P0 pairing of mixed methods), so its saddle point is singular."""
    cells = np.asarray(cells, dtype=np.int64)
    k, m = cells.shape[0], cells.shape[1] // 2
    minus, plus = cells[:, :m].ravel(), cells[:, m:].ravel()
    split = minus != plus
    n = int(cells.max(initial=-1)) + 1
    _, pair = np.unique(minus[split] * n + plus[split], return_inverse=True)
    rows = np.repeat(np.arange(k), m)[split]
    n_pairs = int(pair.max(initial=-1)) + 1
    incidence = sp.csr_matrix((np.ones(rows.shape[0]), (rows, pair.ravel())), shape=(k, n_pairs))
    return (k - int(structural_rank(incidence)) if k else 0), n_pairs


def held_pairs_separated(points: InterfacePoints, hit: np.ndarray) -> np.ndarray:
    """The (minus, plus) pairs (k, 2) whose every corner point is in ``hit``: a pair shared by two cells
    holds while one of its points does."""
    n = int(max(points.minus.max(initial=-1), points.plus.max(initial=-1))) + 1
    key = points.minus * n + points.plus
    gone = np.setdiff1d(key[hit], key[~hit])
    return np.stack([gone // n, gone % n], axis=1) if gone.size else np.zeros((0, 2), dtype=np.int64)


def holding_pairs(points: InterfacePoints, hit: np.ndarray) -> np.ndarray:
    """The (minus, plus) pairs (k, 2) of the points not in ``hit``, each once."""
    keep = ~hit
    return np.unique(np.stack([points.minus[keep], points.plus[keep]], axis=1), axis=0)


class _AtCorners:
    """What corner points change of nodal points: a pair is separated only where all its corner points are."""

    law: TractionLaw | Law3D
    state: np.ndarray
    points: InterfacePoints

    def separated(self, fraction: float) -> tuple[np.ndarray, float]:
        """The pairs all of whose corner points have lost their tensile strength, and the separated size
        (the separated points' weights) [m, m^2]."""
        hit = self.law.separated(self.state, fraction)
        return held_pairs_separated(self.points, hit), float(self.points.weight[hit].sum())

    def holding(self, fraction: float) -> np.ndarray:
        """The (minus, plus) pairs (k, 2) with a corner point that still holds (another MPI rank's
        cells may have separated the pair's other points)."""
        return holding_pairs(self.points, self.law.separated(self.state, fraction))


class CornerEP(_AtCorners, CohesiveEP):
    """EP surfaces with their points at each interface cell's corners (:func:`corner_points`: the nodal
    rule cell by cell)."""


class CornerRP(_AtCorners, CohesiveRP):
    """RP surfaces with their points at each interface cell's corners and one multiplier per cell (the
    module's docstring); no junction term: a cell's constraints close no ring round a node."""

    rings = False

    def __init__(self, points: InterfacePoints, law: TractionLaw | Law3D, augmentation: float, *,
                 name: str = "cohesive", viscosity: float = 0.0):
        """points: :func:`corner_points` of the set's cells."""
        super().__init__(points, law, augmentation, junction=np.zeros(points.n, dtype=bool), name=name,
                         viscosity=viscosity)
        self.corners = points.segments.shape[1] // 2
        # the cells' indices in the whole set (an MPI rank holds some), and each point's cell among them
        self._cells, self._local = np.unique(points.cell, return_inverse=True)
        self.n_cells = self._cells.shape[0]
        self.n_extra = self.dim * self.n_cells
        self._carried = np.zeros((points.n, self.dim))  # r e_a of the last commit, mean-free per cell [Pa]
        self._size = np.bincount(self._local, points.weight, minlength=self.n_cells)

    def set_offset(self, offset: int) -> None:
        """Number the cells' multipliers from ``offset`` on: cell c's are offset + dim c + (0..dim-1), c its
        index in the whole set (on every MPI rank)."""
        self.offset = offset
        self.lam_dofs = offset + self.dim * self.points.cell[:, None] + np.arange(self.dim)
        self.dofs = np.hstack([self.jump_dofs, self.lam_dofs])

    def multiplier_blocks(self) -> np.ndarray:
        """The cells whose multipliers this group holds, by their index in the whole set."""
        return self._cells

    def extra_span(self) -> int:
        return self.dim * (self.total_points // self.corners)

    def redundant_extras(self, dirichlet: np.ndarray) -> np.ndarray:
        """Cell multipliers whose constraint the Dirichlet conditions impose: both nodes of every corner
        pair held in that component (their rows would be empty)."""
        d = self.dim
        held = np.isin(self.jump_dofs, dirichlet)
        first = np.searchsorted(self._local, np.arange(self.n_cells))
        out = []
        for a in range(d):
            free = np.bincount(self._local, ~(held[:, a] & held[:, d + a]), minlength=self.n_cells)
            out.append(self.lam_dofs[first[free == 0], a])
        return np.concatenate(out).astype(np.int64)

    def _cell_mean(self, v: np.ndarray) -> np.ndarray:
        """Each point's cell's weighted mean of v (n_pts, dim)."""
        total = np.zeros((self.n_cells, v.shape[1]))
        np.add.at(total, self._local, self.points.weight[:, None] * v)
        return (total / self._size[:, None])[self._local]

    def _deviations(self, u: np.ndarray) -> np.ndarray:
        """T_a - lambda at the committed tractions, mean-free per cell (n_pts, dim) global [Pa]."""
        t = self.points.from_local(self.state[:, self._t]) - u[self.lam_dofs]
        return t - self._cell_mean(t)

    def evaluate(self, u: np.ndarray, u_n: np.ndarray) -> Evaluation:
        """The corners' augmented returns from the trial lambda + r e_a + r h: the cell's multiplier and
        the corner's carried elastic deviation."""
        self._carried = self._deviations(u_n)
        return super().evaluate(u, u_n)

    def multipliers(self, u: np.ndarray) -> np.ndarray:
        """Each corner's rigid traction lambda + r e_a (global) [Pa]: its cell's multiplier and its carried
        deviation."""
        return u[self.lam_dofs] + self._carried

    def elastic_energy(self, u: np.ndarray) -> float:
        """The corners' deviations' energy sum w_a |T_a - lambda|^2 / (2 r) [J/m, J] at the committed state."""
        dev = self._deviations(u)
        return float(0.5 * np.sum(self.points.weight * np.einsum("pi,pi->p", dev, dev)) / self.aug)
