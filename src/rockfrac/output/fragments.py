"""Fragments: the pieces a mesh with cohesive surfaces has broken into.

Two cells are in one fragment if a path joins them through shared nodes or through interface
node pairs that still hold tension. A pair (one nodal integration point of a cohesive surface,
Sect. 6.2) no longer holds once its law's tensile strength is gone
(:meth:`rockfrac.laws.traction_law.TractionLaw.separated`); a crack that stops inside the mesh
leaves the pairs at its tip unbroken, so a fragment is counted only once a crack separates it
all round. The fragments are the connected components of the graph of the nodes: each cell joins
its nodes, each unbroken pair its two nodes (``scipy.sparse.csgraph``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from rockfrac.fem.kinematics import element_gradients
from rockfrac.fem.reference import ELEMENTS
from rockfrac.mesh.mesh import Mesh

CHUNK = 20_000  # cells whose shape gradients are made at once (about 30 MB for hexahedra)


@dataclass
class Pieces:
    """The fragments at one state: each cell's fragment (0 .. count - 1, the largest first), and each
    fragment's cells, size [m^2 in 2D, m^3 in 3D] and centroid [m]."""

    cell_fragment: np.ndarray
    cells: np.ndarray
    size: np.ndarray
    centroid: np.ndarray

    @property
    def count(self) -> int:
        return int(self.size.shape[0])


class Fragments:
    """The fragment graph of a split mesh: fixed cell links, the interface pairs broken per state."""

    def __init__(self, mesh: Mesh):
        self.n_nodes = mesh.n_nodes
        cells = mesh.cells
        k = cells.shape[1]
        star = np.stack([np.repeat(cells[:, 0], k - 1), cells[:, 1:].ravel()], axis=1)  # each cell joins its nodes
        half = mesh.interfaces.shape[1] // 2
        pairs = np.stack([mesh.interfaces[:, :half].ravel(), mesh.interfaces[:, half:].ravel()], axis=1)
        pairs = np.unique(np.sort(pairs[pairs[:, 0] != pairs[:, 1]], axis=1), axis=0)  # each pair once
        self._star, self._pairs = star, pairs
        self._pair_keys = self._keys(pairs)
        self._first = cells[:, 0]
        self._mesh = mesh
        self._volume: np.ndarray | None = None  # the cells' sizes, made when first needed
        self._last: tuple[bytes, Pieces] | None = None

    def _volumes(self) -> np.ndarray:
        """Each cell's area or volume [m^2 or m^3] (its quadrature's det J w), a block of cells at a
        time: the shape gradients of a whole 3D mesh at once would take GBs."""
        if self._volume is None:
            mesh, ref = self._mesh, ELEMENTS[self._mesh.cell_type]
            self._volume = np.concatenate([element_gradients(mesh.nodes[mesh.cells[a:a + CHUNK]], ref)[1].sum(axis=1)
                                           for a in range(0, mesh.cells.shape[0], CHUNK)])
        return self._volume

    def _keys(self, pairs: np.ndarray) -> np.ndarray:
        """One integer per node pair, whichever node is listed first."""
        return pairs.min(axis=1) * self.n_nodes + pairs.max(axis=1)

    def pieces(self, separated: np.ndarray, held: np.ndarray | None = None) -> Pieces:
        """The fragments when the (k, 2) (minus, plus) pairs ``separated`` no longer hold, but for those
        also in ``held`` (a pair some other points still hold: corner points on another MPI rank)."""
        keys = np.unique(self._keys(np.asarray(separated, dtype=np.int64).reshape(-1, 2)))
        if held is not None and held.size:
            keys = np.setdiff1d(keys, self._keys(np.asarray(held, dtype=np.int64).reshape(-1, 2)))
        tag = keys.tobytes()
        if self._last is not None and self._last[0] == tag:  # no point broke since the last state
            return self._last[1]
        holding = self._pairs[~np.isin(self._pair_keys, keys)]
        edges = np.concatenate([self._star, holding])
        graph = sp.coo_matrix((np.ones(edges.shape[0], dtype=np.int32), (edges[:, 0], edges[:, 1])),
                              shape=(self.n_nodes, self.n_nodes)).tocsr()
        _, node_label = connected_components(graph, directed=False)
        _, label = np.unique(node_label[self._first], return_inverse=True)
        volume = self._volumes()
        size = np.bincount(label, weights=volume)
        order = np.argsort(-size, kind="stable")  # the largest fragment first
        rank = np.empty_like(order)
        rank[order] = np.arange(order.shape[0])
        label = rank[label]
        size = size[order]
        centre = self._mesh.nodes[self._mesh.cells].mean(axis=1)
        centroid = np.stack([np.bincount(label, weights=volume * centre[:, a]) for a in range(centre.shape[1])],
                            axis=1) / size[:, None]
        out = Pieces(label, np.bincount(label), size, centroid)
        self._last = (tag, out)
        return out
