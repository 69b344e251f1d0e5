"""Rank 0's part of an MPI run's set-up: the whole mesh made, split where cohesive surfaces go and
partitioned once, the inputs that name its groups checked on it, and each rank's :class:`Share`
cut from it: the rank's piece of the mesh (:mod:`rockfrac.mesh.piece`), its share of the
partition, its cohesive points and its monitors on the piece's nodes.

A rank's piece is its own cells and interface cells, and the interface cells its cohesive points
lie on (a point's weight and normal come from every cell of its node pair). With embedded cracks it
also holds every cell that shares a side with one of its own (its halo): a crack grows from a cell
into its neighbours (rockfrac.elements.ede_paths.CrackPaths). With nodal embedded cracks the halo
is every cell that shares a node with one of its own: whether a node carries a crack's enrichment
depends on every cell round it (rockfrac.elements.ede_enrichment), and rank 0 sends the nodes the
enrichment numbers, with their owners.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, replace

import numpy as np

from rockfrac.case.build_groups import check_cell_multipliers, is_embedded, material_cells, set_points
from rockfrac.case.build_mesh import insert_cohesive, make_mesh
from rockfrac.case.build_program import check_boundary_groups, resolve_monitors
from rockfrac.case.cohesive_section import CohesiveForm
from rockfrac.case.schema import Case
from rockfrac.elements.interface_points import InterfacePoints
from rockfrac.mesh.interfaces import at_junctions, looped_pairs_by_set, tied_nodes
from rockfrac.mesh.mesh import Mesh
from rockfrac.mesh.partition import Partition, RankPartition
from rockfrac.mesh.piece import Cutter
from rockfrac.mesh.topology import cell_sides, same_nodes
from rockfrac.output.history import Monitor


@dataclass
class CohesiveShare:
    """A rank's points of one cohesive set (on its piece's nodes), how many the set has, the bulk
    group on each point's minus side (its in-situ stress), and for a rigid-plastic set how many
    multiplier blocks each rank has (a block per point, or per cell for corner points; beside nodal
    cracks, whose enrichments are numbered knowing every one's rank, each block's rank), which of the
    rank's points sit at a junction (a node split into three copies or more, in the whole mesh) and
    which lie on loops of pairs of every set (:func:`looped_pairs_by_set`)."""

    points: InterfacePoints
    total: int
    minus_group: np.ndarray  # the bulk group (material) of the cells round each point's minus node, the last
    owner_counts: np.ndarray | None = None  # rigid-plastic: the set's multiplier blocks on each rank
    owners: np.ndarray | None = None  # rigid-plastic beside nodal cracks: each block's rank
    junction: np.ndarray | None = None
    on_loops: np.ndarray | None = None  # rigid-plastic: which of the rank's points lie on loops of pairs


@dataclass
class Share:
    """What rank 0 sends a rank: the case (its defaults resolved on the whole mesh), the rank's piece
    of the split mesh and share of the partition, its points of each cohesive set and its monitors
    on the piece. ``whole``: the whole split mesh, on rank 0 only (never sent)."""

    case: Case
    mesh: Mesh
    partition: RankPartition
    cohesive: list[CohesiveShare]
    monitors: list[Monitor]
    whole: Mesh | None = None
    cell_serial: np.ndarray | None = None  # each piece cell's index among its material's cells in the whole mesh
    enrichment: tuple[np.ndarray, np.ndarray] | None = None  # nodal cracks: their nodes (whole ids), their ranks


def _on_piece(points: InterfacePoints, ids: np.ndarray) -> InterfacePoints:
    """Points with their nodes in a piece's numbering (``ids``: the whole index of each piece node)."""
    return replace(points, minus=np.searchsorted(ids, points.minus), plus=np.searchsorted(ids, points.plus),
                   segments=np.searchsorted(ids, points.segments))


def cut_shares(case: Case, path: str, n_ranks: int, split) -> tuple[Mesh, Iterator[Share]]:
    """The whole split mesh, every input error raised, and the ranks' shares, cut one at a time in
    rank order as they are taken (``case`` resolved; ``split(mesh)``: the partition)."""
    mesh, set_cells = insert_cohesive(case, make_mesh(case, path), path)
    part: Partition = split(mesh)
    node_group = np.full(mesh.n_nodes, -1)  # the last bulk group (material) whose cells hold each node
    serial = np.zeros(mesh.cells.shape[0], dtype=np.int64)  # each cell's index among its material's
    ede = [np.zeros(0, dtype=np.int64)]  # the cells with embedded cracks
    for k, (material, cells, region) in enumerate(material_cells(case, mesh, path)):  # every cell one material
        node_group[mesh.cells[cells].ravel()] = k
        serial[cells] = np.arange(cells.size)
        if is_embedded(case, material, region):
            ede.append(cells)
    check_boundary_groups(case, mesh, path)
    monitors = resolve_monitors(case, mesh, path)
    rigid = any(section.form is CohesiveForm.rp for section in case.cohesive_sets)
    root = tied_nodes(mesh) if rigid else None
    sets = []
    for k, (section, cells) in enumerate(zip(case.cohesive_sets, set_cells)):
        points = set_points(section, mesh, cells, root)
        check_cell_multipliers(section, points, f"cohesive {k + 1}", path)
        where = part.interface_part[cells[points.cell]]  # each point on the rank of its first interface cell
        nodal_rp = section.form is CohesiveForm.rp and section.points == "nodes"  # facet points: no junction term
        junction = at_junctions(mesh, points.minus, root) if nodal_rp else None
        # each multiplier block's rank (RP): a point's own, or a cell's for corner points (one per cell)
        lams = where[points.segment_points[:, 0]] if section.points == "corners" else where
        sets.append((section, cells, points, where, junction, lams))
    loops = None  # rigid-plastic surfaces: the pairs of every set on loops round a node (run.log warns)
    if rigid:
        loops = looped_pairs_by_set([s[2].minus for s in sets], [s[2].plus for s in sets], mesh.n_nodes)
    emb = case.embedded
    nodal = emb is not None and emb.kinematics == "nodal"
    enrichment = None
    if nodal:  # the nodes the enrichment numbers, each with its rank
        nodes = np.unique(mesh.cells[np.concatenate(ede)])
        enrichment = (nodes, part.node_part[nodes])
    sides = side_ids(mesh) if emb is not None and not nodal else None  # a halo across the sides
    cutter = Cutter(mesh)
    return mesh, _shares(case, mesh, part, cutter, sets, node_group, monitors, n_ranks, loops, serial,
                         Halo(sides, nodal), enrichment)


@dataclass(frozen=True)
class Halo:
    """Which cells beside its own a rank's piece holds: none, those across a side (``sides``:
    :func:`side_ids`), or every cell sharing a node with one of its own (``by_nodes``)."""

    sides: np.ndarray | None
    by_nodes: bool

    def of(self, mesh: Mesh, own: np.ndarray) -> np.ndarray:
        """The halo cells of the ``own`` cells (a mask over the cells)."""
        if self.by_nodes:
            touched = np.zeros(mesh.n_nodes, dtype=bool)
            touched[mesh.cells[own].ravel()] = True
            return np.flatnonzero(touched[mesh.cells].any(axis=1) & ~own)
        if self.sides is not None:
            return halo(self.sides, own)
        return np.zeros(0, dtype=np.int64)


def side_ids(mesh: Mesh) -> np.ndarray:
    """An id per side of each cell (n_cells, sides per cell), shared by the cells on both sides of it."""
    n = mesh.cells.shape[0]
    return same_nodes(cell_sides(mesh.cells, mesh.dim)).reshape(n, -1)


def halo(sides: np.ndarray, own: np.ndarray) -> np.ndarray:
    """The cells that share a side with one of the ``own`` cells (a mask over the cells), own cells
    excluded (``sides``: :func:`side_ids`)."""
    touched = np.zeros(int(sides.max(initial=-1)) + 1, dtype=bool)
    touched[sides[own].ravel()] = True
    return np.flatnonzero(touched[sides].any(axis=1) & ~own)


def _shares(case: Case, mesh: Mesh, part: Partition, cutter: Cutter, sets: list, node_group: np.ndarray,
            monitors: list[Monitor], n_ranks: int, loops: list | None, serial: np.ndarray, near: Halo,
            enrichment: tuple[np.ndarray, np.ndarray] | None) -> Iterator[Share]:
    """Each rank's share in turn (see :func:`cut_shares`)."""
    blocks = part.node_blocks()
    for r in range(n_ranks):
        held = [cells[((where[p.segment_points] == r) & (p.segment_points >= 0)).any(axis=1)]
                for _, cells, p, where, _, _ in sets]
        own = part.cell_part == r
        piece = cutter.piece(np.concatenate([np.flatnonzero(own), near.of(mesh, own)]),
                             np.concatenate([np.flatnonzero(part.interface_part == r)] + held))
        ids = piece.place.nodes  # type: ignore[union-attr]
        coh = []
        for k, (section, _, p, where, junction, lams) in enumerate(sets):
            rp = section.multiplier_unknowns  # numbered over the ranks
            coh.append(CohesiveShare(_on_piece(p.subset(where == r), ids), p.n, node_group[p.minus[where == r]],
                                     np.bincount(lams, minlength=n_ranks) if rp else None,
                                     lams if rp and enrichment is not None else None,
                                     junction[where == r] if junction is not None else None,
                                     loops[k][where == r] if loops is not None else None))
        place = piece.place
        assert place is not None
        yield Share(case, piece, part.of_piece(r, place.cells, place.interfaces, ids, blocks), coh,
                    [m.on_piece(ids) for m in monitors], cell_serial=serial[place.cells], enrichment=enrichment)
