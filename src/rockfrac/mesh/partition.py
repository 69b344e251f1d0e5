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

    def numbering(self, part: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """From one sort of the blocks (a rank's set-up sorts once, not once per part): every dof's
        renumbered index (:meth:`new_dofs`), each part's first renumbered dof (n_parts + 1,), and the
        part's own dofs (:meth:`owned_dofs`)."""
        order, starts = self._blocks()
        new = np.empty_like(order)
        new[order] = np.arange(order.shape[0])
        blocks = order[starts[part]:starts[part + 1]]
        comps = np.arange(self.dim)
        return ((self.dim * new[:, None] + comps).ravel(), self.dim * starts,
                (self.dim * blocks[:, None] + comps).ravel())

    def owned_range(self, part: int) -> tuple[int, int]:
        """The part's block of renumbered dofs [start, end)."""
        _, starts = self._blocks()
        return self.dim * int(starts[part]), self.dim * int(starts[part + 1])

    def owned_dofs(self, part: int) -> np.ndarray:
        """The part's dofs in the original numbering, in the order of their renumbered indices."""
        order, starts = self._blocks()
        blocks = order[starts[part]:starts[part + 1]]
        return (self.dim * blocks[:, None] + np.arange(self.dim)).ravel()


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
