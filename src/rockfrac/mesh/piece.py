"""One MPI rank's piece of a mesh: some of its cells and interface cells, the nodes they use, and the
named groups restricted to them, renumbered 0 .. n - 1 in the whole mesh's order.

Rank 0 cuts the pieces from the whole (split) mesh and sends each rank its own; a rank then never
holds the whole mesh. The piece's ``place`` (:class:`rockfrac.mesh.mesh.PlaceInWhole`) says where it
sits in the whole: the whole mesh's index of each node, cell and interface cell (ascending, so the
piece keeps the whole mesh's relative order, and anything sorted by node index sorts alike in
both), the whole mesh's counts, the sides of the whole body's outer boundary on the piece's cells,
the whole node groups' sizes and the whole mesh's bounding box.
"""

from __future__ import annotations

import numpy as np

from rockfrac.mesh.mesh import Mesh, PlaceInWhole
from rockfrac.mesh.topology import outer_boundary, side_cells


class Cutter:
    """What cutting pieces from one whole mesh needs once: each boundary side's cell (named side
    groups and the outer boundary)."""

    def __init__(self, mesh: Mesh):
        self.mesh = mesh
        sets = mesh.edge_sets if mesh.dim == 2 else mesh.face_sets
        self.outer = outer_boundary(mesh)
        groups = list(sets.values()) + [self.outer]
        width = self.outer.shape[1]  # one search over the cells' sides for every group
        cells = side_cells(mesh, np.vstack([np.asarray(g, dtype=np.int64).reshape(-1, width) for g in groups]))
        parts = np.split(cells, np.cumsum([len(g) for g in groups])[:-1])
        self.side_cells = dict(zip(sets, parts[:-1]))
        self.outer_cells = parts[-1]

    def piece(self, cells: np.ndarray, interfaces: np.ndarray, nodes: np.ndarray | None = None) -> Mesh:
        """The piece of the given cells and interface cells (whole mesh's indices), with the nodes
        they use and any more ``nodes`` (whole indices). Node groups keep their nodes in the piece,
        side groups and the outer boundary the sides of its cells, regions its cells; every group
        keeps its name, also where it has nothing in the piece."""
        mesh = self.mesh
        cells = np.unique(np.asarray(cells, dtype=np.int64))
        interfaces = np.unique(np.asarray(interfaces, dtype=np.int64))
        used = [mesh.cells[cells].ravel(), mesh.interfaces[interfaces].ravel()]
        if nodes is not None:
            used.append(np.asarray(nodes, dtype=np.int64))
        ids = np.unique(np.concatenate(used))
        local = np.full(mesh.n_nodes, -1, dtype=np.int64)
        local[ids] = np.arange(ids.shape[0])
        in_piece = np.zeros(mesh.cells.shape[0], dtype=np.bool_)
        in_piece[cells] = True

        def sides_of(sides: np.ndarray, where: np.ndarray) -> np.ndarray:
            return local[sides[(where >= 0) & in_piece[np.maximum(where, 0)]]]

        side_sets = {name: sides_of(sides, self.side_cells[name])
                     for name, sides in (mesh.edge_sets if mesh.dim == 2 else mesh.face_sets).items()}
        node_sets = {name: local[n[local[n] >= 0]] for name, n in mesh.node_sets.items()}
        regions = {name: np.searchsorted(cells, r[in_piece[r]]) for name, r in mesh.regions.items()}
        place = PlaceInWhole(ids, cells, interfaces, mesh.n_nodes, mesh.cells.shape[0], mesh.interfaces.shape[0],
                      sides_of(self.outer, self.outer_cells), {n: len(v) for n, v in mesh.node_sets.items()},
                      mesh.bounds)
        return Mesh(mesh.nodes[ids], local[mesh.cells[cells]], mesh.cell_type,
                    interfaces=local[mesh.interfaces[interfaces]], node_sets=node_sets,
                    edge_sets=side_sets if mesh.dim == 2 else {}, face_sets=side_sets if mesh.dim == 3 else {},
                    regions=regions, place=place)
