"""Partition a mesh for MPI runs: METIS on the element graph, cohesive elements included.

The graph's vertices are the bulk cells and the interface cells (after cohesive insertion), two of
them adjacent where they share a node; an interface cell holds its minus and plus nodes, so it
ties the cells on both of its sides together. ``pymetis.part_graph`` splits the graph into parts of
equal element counts with a small cut. Each node belongs to the lowest part among the bulk cells
around it (every node of a split mesh is a corner of a bulk cell, so its owner assembles there);
the dofs are renumbered so that every part owns one contiguous block (``dim`` dofs per
node, in the order of the parts, the original node order within a part): the row layout of PETSc's
distributed matrices and vectors.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
import scipy.sparse as sp

from rockfrac.mesh.mesh import Mesh


@dataclass(frozen=True)
class Partition:
    """Which part owns each cell, interface cell and node, and the dof renumbering by parts.

    cell_part, interface_part, node_part: the owning part of each bulk cell, interface cell, node.
    node_order: the nodes sorted by (part, index): node_order[k] gets the new index k.
    node_starts: (n_parts + 1,) the new node indices of part r are node_starts[r] .. node_starts[r+1]
    (without extra dofs).
    extra_part: the owning part of each block of ``dim`` extra dofs (see :meth:`with_extras`).
    """

    n_parts: int
    dim: int
    cell_part: np.ndarray
    interface_part: np.ndarray
    node_part: np.ndarray
    node_order: np.ndarray
    node_starts: np.ndarray

    extra_part: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))

    @property
    def n_dofs(self) -> int:
        return self.dim * (self.node_part.shape[0] + self.extra_part.shape[0])

    def with_extras(self, extra_part: np.ndarray) -> Partition:
        """The partition with blocks of ``dim`` extra dofs after the node dofs (rigid-plastic
        multipliers, one block per interface point, in the model's numbering), each owned by
        ``extra_part``: a part's PETSc block is its nodes' dofs, then its extra blocks'."""
        return replace(self, extra_part=np.asarray(extra_part, dtype=np.int64))

    def _blocks(self) -> tuple[np.ndarray, np.ndarray]:
        """The blocks (nodes, then extras) sorted by (part, nodes first, index), and each part's first."""
        part = np.concatenate([self.node_part, self.extra_part])
        kind = np.repeat([0, 1], [self.node_part.shape[0], self.extra_part.shape[0]])
        order = np.lexsort((np.arange(part.shape[0]), kind, part))
        return order, np.searchsorted(part[order], np.arange(self.n_parts + 1))

    def new_dofs(self) -> np.ndarray:
        """(n_dofs,) the renumbered (PETSc) index of every dof: block b's component k is dim b + k
        (node n is block n; extra block e is block n_nodes + e)."""
        order, _ = self._blocks()
        new = np.empty_like(order)
        new[order] = np.arange(order.shape[0])
        return (self.dim * new[:, None] + np.arange(self.dim)).ravel()

    def owned_range(self, part: int) -> tuple[int, int]:
        """The part's block of renumbered dofs [start, end)."""
        _, starts = self._blocks()
        return self.dim * int(starts[part]), self.dim * int(starts[part + 1])

    def owned_dofs(self, part: int) -> np.ndarray:
        """The part's dofs in the original numbering, in the order of their renumbered indices."""
        order, starts = self._blocks()
        blocks = order[starts[part]:starts[part + 1]]
        return (self.dim * blocks[:, None] + np.arange(self.dim)).ravel()


    def node_blocks(self) -> np.ndarray:
        """Each node's place in its part's block of nodes (its renumbered index without extra dofs,
        less its part's first)."""
        place = np.empty_like(self.node_order)
        place[self.node_order] = np.arange(self.node_order.shape[0]) - self.node_starts[self.node_part[self.node_order]]
        return place

    def of_piece(self, rank: int, cells: np.ndarray, interfaces: np.ndarray, nodes: np.ndarray,
                 blocks: np.ndarray | None = None) -> RankPartition:
        """What rank ``rank`` needs of the partition for its piece of the mesh (the whole mesh's
        indices of the piece's cells, interface cells and nodes, each ascending; ``blocks``:
        :meth:`node_blocks`, made once for every rank's piece)."""
        blocks = self.node_blocks() if blocks is None else blocks
        return RankPartition(self.n_parts, self.dim, rank, self.cell_part[cells], self.interface_part[interfaces],
                             self.node_part[nodes], blocks[nodes], np.diff(self.node_starts),
                             np.asarray(nodes, dtype=np.int64), self.node_part.shape[0], self.extra_part)


@dataclass(frozen=True)
class RankPartition:
    """One rank's share of a :class:`Partition`: the parts of its piece's cells, interface cells and
    nodes, and what numbers their dofs in PETSc's order, nothing of the whole mesh's size.

    node_ids: the whole mesh's index of each of the piece's nodes (ascending); node_block: each one's
    place in its part's block of nodes; node_counts: (n_parts,) the nodes of each part; n_nodes: the
    whole mesh's. Dofs are numbered as in the whole :class:`Partition` (the global numbering: node n's
    component k is dim n + k, extra block e's is dim (n_nodes + e) + k), and renumbered alike.
    """

    n_parts: int
    dim: int
    rank: int
    cell_part: np.ndarray
    interface_part: np.ndarray
    node_part: np.ndarray
    node_block: np.ndarray
    node_counts: np.ndarray
    node_ids: np.ndarray
    n_nodes: int
    extra_part: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    extra_counts: np.ndarray | None = None  # the extra blocks of each part, when only the rank's own are known
    own_extras: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))

    @property
    def n_extras(self) -> int:
        return int(self.extra_counts.sum()) if self.extra_counts is not None else self.extra_part.shape[0]

    @property
    def n_dofs(self) -> int:
        return self.dim * (self.n_nodes + self.n_extras)

    def with_extras(self, extra_part: np.ndarray) -> RankPartition:
        """As :meth:`Partition.with_extras` (``extra_part``: every extra block's owner, the whole model's)."""
        return replace(self, extra_part=np.asarray(extra_part, dtype=np.int64), extra_counts=None)

    def with_own_extras(self, counts: np.ndarray, own: np.ndarray) -> RankPartition:
        """The extra blocks known by their count in each part and by this rank's own (their indices,
        ascending): nothing of the whole model's size, for a rank whose groups touch only its own
        extra dofs (rigid-plastic multipliers)."""
        return replace(self, extra_part=np.zeros(0, dtype=np.int64), extra_counts=np.asarray(counts, dtype=np.int64),
                       own_extras=np.asarray(own, dtype=np.int64))

    def numbering(self) -> tuple[np.ndarray, np.ndarray, PetscIndex]:
        """Each part's first renumbered dof (n_parts + 1,), this rank's own dofs (global numbering,
        in renumbered order) and the map of global dofs (of the piece's nodes and any extras) to
        renumbered ones."""
        known = self.extra_counts is None  # every extra block's owner, or this rank's own blocks only
        counts = np.bincount(self.extra_part, minlength=self.n_parts) if known else self.extra_counts
        assert counts is not None
        first = np.concatenate([[0], np.cumsum(self.node_counts + counts)])
        if known:
            order = np.argsort(self.extra_part, kind="stable")  # extras by part, then by index
            part = self.extra_part[order]
            extra_ids = np.arange(order.shape[0])
            extra_block = np.empty_like(order)
            extra_block[order] = (np.arange(order.shape[0]) - np.concatenate([[0], np.cumsum(counts)])[part]
                                  + first[part] + self.node_counts[part])
            own = np.flatnonzero(self.extra_part == self.rank)
        else:
            extra_ids = own = self.own_extras
            extra_block = first[self.rank] + self.node_counts[self.rank] + np.arange(own.shape[0])
        node_block = first[self.node_part] + self.node_block
        mine = np.flatnonzero(self.node_part == self.rank)
        blocks = np.concatenate([self.node_ids[mine[np.argsort(self.node_block[mine])]], self.n_nodes + own])
        comps = np.arange(self.dim)
        owned = (self.dim * blocks[:, None] + comps).ravel()
        return self.dim * first, owned, PetscIndex(self.dim, self.node_ids, node_block, self.n_nodes, extra_ids,
                                                   extra_block)


@dataclass(frozen=True)
class PetscIndex:
    """The renumbered (PETSc) index of global dofs: of a piece's nodes and of the extra dofs."""

    dim: int
    node_ids: np.ndarray
    node_block: np.ndarray
    n_nodes: int
    extra_ids: np.ndarray  # the extra blocks known here (ascending)
    extra_block: np.ndarray

    def __call__(self, dofs: np.ndarray) -> np.ndarray:
        dofs = np.asarray(dofs, dtype=np.int64)
        block, comp = np.divmod(dofs, self.dim)
        node = block < self.n_nodes
        out = np.empty_like(block)
        out[node] = self.node_block[_find(self.node_ids, block[node], "dofs of nodes outside this rank's piece")]
        out[~node] = self.extra_block[_find(self.extra_ids, block[~node] - self.n_nodes,
                                            "extra dofs another rank owns (only the rank's own are known here)")]
        return self.dim * out + comp


def _find(ids: np.ndarray, wanted: np.ndarray, what: str) -> np.ndarray:
    """The places of ``wanted`` in the ascending ``ids``, every one of them there (else ValueError)."""
    at = np.searchsorted(ids, wanted)
    if wanted.size and (at.max() >= ids.shape[0] or np.any(ids[at] != wanted)):
        raise ValueError(what)
    return at


def element_graph(mesh: Mesh) -> sp.csr_matrix:
    """Adjacency of the cells and interface cells (cells first) through shared nodes, no diagonal."""
    elements = [mesh.cells, mesh.interfaces]
    rows = np.concatenate([np.repeat(np.arange(e.shape[0]) + off, e.shape[1])
                           for e, off in zip(elements, (0, mesh.cells.shape[0]))])
    cols = np.concatenate([e.ravel() for e in elements])
    n_el = mesh.cells.shape[0] + mesh.interfaces.shape[0]
    incidence = sp.csr_matrix((np.ones(rows.shape[0]), (rows, cols)), shape=(n_el, mesh.n_nodes))
    graph = (incidence @ incidence.T).tocsr()
    graph.setdiag(0.0)
    graph.eliminate_zeros()
    graph.sort_indices()
    return graph


def partition(mesh: Mesh, n_parts: int) -> Partition:
    """Split the mesh's cells and interface cells into ``n_parts`` parts (METIS) and number the
    dofs by part; one part: everything in part 0, the numbering unchanged."""
    if n_parts < 1:
        raise ValueError(f"a partition needs at least one part, got {n_parts}")
    n_cells, n_if = mesh.cells.shape[0], mesh.interfaces.shape[0]
    n_el = n_cells + n_if
    if n_parts > n_el:
        raise ValueError(f"{n_parts} parts for {n_el} elements: each part needs at least one element")
    if n_parts == 1:
        part = np.zeros(n_el, dtype=np.int64)
    else:
        import pymetis

        graph = element_graph(mesh)
        _, labels = pymetis.part_graph(n_parts, pymetis.CSRAdjacency(graph.indptr, graph.indices))
        part = np.asarray(labels, dtype=np.int64)
        if np.unique(part).shape[0] != n_parts:  # METIS may leave a part empty on a tiny graph
            raise ValueError(f"METIS left a part empty splitting {n_el} elements into {n_parts} parts")
    node_part = np.full(mesh.n_nodes, n_parts, dtype=np.int64)
    np.minimum.at(node_part, mesh.cells.ravel(), np.repeat(part[:n_cells], mesh.cells.shape[1]))
    node_part[node_part == n_parts] = 0  # nodes of no cell (none in a checked mesh)
    order = np.lexsort((np.arange(mesh.n_nodes), node_part))
    starts = np.searchsorted(node_part[order], np.arange(n_parts + 1))
    return Partition(n_parts, mesh.dim, part[:n_cells], part[n_cells:], node_part, order, starts)
