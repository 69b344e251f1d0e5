"""Which nodes carry a nodal embedded crack's enrichment, and their unknowns (rockfrac.elements.ede_nodal).

One registry for every nodal-crack group of a model (a crack crosses regions): it numbers an
enrichment q (one per node and direction) for every node of those groups, after the model's
displacements (rockfrac.elements.ede_nodal_parts.HeldEnrichment owns them).

A node carries the enrichment of the crack that cuts its cells (the first, where two meet) unless
it lies on a crack-tip edge: an edge where a crack ends that an uncut cell shares. There the jump
must vanish (the crack closes at its tip), and a tip edge's nodes carry no enrichment, so that the
uncut cell beyond, which ignores enrichments, and the cut cell agree along the edge. When the crack
grows into that cell the edge is no longer a tip, its nodes take the enrichment, starting from zero:
the displacement does not change. The q of a node without enrichment is held at zero
(rockfrac.elements.ede_nodal_parts.HeldEnrichment).

A crack that reaches a loaded boundary splits the load of the edge it crosses between the two sides
(:meth:`EnrichmentRegistry.surface_forces`); the q of a node whose displacement is prescribed is
prescribed too (a crack does not open across a support).

On several MPI ranks every rank numbers the nodes of every rank's cells alike, and each cut is
entered on every rank when its owner announces it (the sides its crack crosses, the traces on them,
the cell's nodes, and the cracks it joins), in the serial order, so that cracks and crack ids are
the same everywhere. Nodes and cells are named by their index in the whole mesh. A rank whose mesh
is a piece of the whole (its own cells and every cell sharing a node with one) knows the sides of
the cells it sees only: that is enough to decide the tips and enrichments of its own cells' nodes,
and the owner of a cut, which sees all its neighbours, finds the cracks it joins. A rank computes
the boundary loads' share of its own cut cells only.
"""

from __future__ import annotations

import numpy as np

from rockfrac.elements.ede_paths import Alone, Exchange
from rockfrac.fem.dofs import Numbering
from rockfrac.mesh.mesh import PlaceInWhole


def side_key(nodes) -> tuple[int, ...]:
    """A cell side (an edge in 2D, a face in 3D) as its sorted mesh nodes."""
    return tuple(sorted(int(v) for v in nodes))


def cell_sides(cells: np.ndarray, dim: int) -> list[tuple[int, ...]]:
    """The sides of a cell type as local node lists: a 2D cell's edges (k to k + 1), a 3D cell's faces."""
    from rockfrac.fem.cut_cell import FACES

    k = cells.shape[1]
    if dim == 2:
        return [(a, (a + 1) % k) for a in range(k)]
    return FACES["tet4" if k == 4 else "hex8"]


class EnrichmentRegistry:
    """The enriched unknowns of a model's nodal-crack groups (module doc).

    groups: the groups (each with ``cells`` (n_el, k) mesh nodes and ``whole_ids`` their cells in the
    whole mesh); mesh_cells: every cell of the mesh (n, k) (the neighbours across crack-tip sides). A
    group tells where its cut cell e's crack crosses the cell's sides: ``crossed_sides(e)``, a list
    of (side's mesh nodes, the crack's trace on it: its end point in 2D, its segment on the face in 3D).
    """

    def __init__(self, groups: list, mesh_cells: np.ndarray, dim: int = 2, every_cell: list | None = None,
                 exchange: Exchange | None = None, rank: int = 0, place: PlaceInWhole | None = None,
                 nodes: np.ndarray | None = None):
        """every_cell: each group's cells (mesh nodes) on every MPI rank (default: the groups' own);
        exchange: the ranks' (the cuts are then announced: see :meth:`announce`), of which this is
        ``rank``; place: where the mesh sits in the whole one (an MPI rank's piece; default: the mesh
        is whole); nodes: the registry's nodes, the whole mesh's ids of every group's cells' nodes on
        every rank (default: those of every_cell)."""
        self.groups = groups
        self.dim = dim
        self.place = place
        cells = every_cell if every_cell is not None else [g.cells for g in groups]
        if nodes is None:
            nodes = np.unique(np.concatenate([self._whole(np.asarray(c)).ravel() for c in cells]))
        self.nodes = np.asarray(nodes, dtype=np.int64)  # whole mesh ids, ascending
        self.exchange: Exchange = exchange if exchange is not None else Alone()
        self.distributed = exchange is not None
        self.rank = rank
        self.offset = 0
        self.numbering: Numbering | None = None  # an MPI rank's local dofs (None: the global numbering)
        self.enriched = np.zeros(self.nodes.size, dtype=bool)
        self.crack_of = np.full(self.nodes.size, -1)
        self.version = 0
        self.dirty = False
        self.side_cells: dict[tuple[int, ...], list[int]] = {}  # by the sides' whole mesh nodes: whole cell ids
        local = cell_sides(mesh_cells, dim)
        whole_cells = place.cells if place is not None else np.arange(mesh_cells.shape[0])
        for c, conn in zip(whole_cells.tolist(), self._whole(mesh_cells).tolist()):
            for side in local:
                self.side_cells.setdefault(side_key(conn[a] for a in side), []).append(c)
        # every cut cell (any rank's): its owner here (group, local cell; -1, -1 on another rank), its
        # crack id, the sides it crosses with the crack's traces on them, its mesh nodes (whole ids)
        self.cut: dict[int, tuple[int, int, int]] = {}
        self.cut_sides: dict[int, list[tuple[tuple[int, ...], np.ndarray]]] = {}
        self.cut_nodes: dict[int, tuple[int, ...]] = {}
        self.cut_order: list[int] = []
        self.parent: list[int] = []  # crack ids joined into cracks (union-find)
        self.cracks = 0
        self._restored: set[int] = set()
        self._pending: dict[int, tuple[int, int]] = {}  # own cuts not announced yet (several ranks)

    def _whole(self, nodes: np.ndarray) -> np.ndarray:
        """The whole mesh's ids of mesh nodes (any shape)."""
        return nodes if self.place is None else self.place.nodes[nodes]

    def _piece(self, nodes: tuple[int, ...]) -> tuple[int, ...]:
        """Nodes by whole mesh id in the mesh's own numbering."""
        if self.place is None:
            return nodes
        return tuple(int(v) for v in np.searchsorted(self.place.nodes, nodes))

    def _crossed(self, group, local: int) -> list[tuple[tuple[int, ...], np.ndarray]]:
        """A group's cut cell's crossed sides, their nodes by whole mesh id."""
        return [(tuple(int(v) for v in self._whole(np.asarray(n))), t) for n, t in group.crossed_sides(local)]

    # -- numbering ----------------------------------------------------------------------------
    @property
    def size(self) -> int:
        """The number of enriched unknowns (every node, every direction)."""
        return self.dim * self.nodes.size

    def index(self, nodes: np.ndarray) -> np.ndarray:
        """The registry's index of nodes by their whole mesh ids (any shape)."""
        return np.searchsorted(self.nodes, nodes)

    def dofs(self, cells: np.ndarray) -> np.ndarray:
        """The q unknowns (n_el, dim k) of cells (n_el, k) of mesh nodes, node by node."""
        i = self.index(self._whole(cells))
        q = self.offset + self.dim * i[..., None] + np.arange(self.dim)
        return self._local(q.reshape(cells.shape[0], self.dim * cells.shape[1]))

    def _local(self, q: np.ndarray) -> np.ndarray:
        """Global q dofs in the model's numbering (an MPI rank's local one, once renumbered)."""
        return q if self.numbering is None else self.numbering.local(q)

    def set_offset(self, offset: int) -> None:
        """Number the q's from ``offset``."""
        self.offset = offset
        self.version += 1  # the cut cells' dofs change with it

    # -- the cuts ------------------------------------------------------------------------------
    def register_cut(self, group, local: int) -> None:
        """A cell of ``group`` has been cut: on one process, entered at once (:meth:`_enter`); on
        several ranks, when every rank announces it (:meth:`announce`, in the same order)."""
        gcell = int(group.whole_ids[local])
        if self.distributed:
            self._pending[gcell] = (self.groups.index(group), local)
            return
        sides = self._crossed(group, local)
        volume = float(group.wdet[local].sum())
        self._enter(gcell, sides, self._whole(group.cells[local]), self._joins(gcell, sides, volume),
                    (self.groups.index(group), local))

    def announce(self, gcell: int) -> None:
        """Every rank: enter the cut of mesh cell gcell as its owner made it, joined to the cracks the
        owner finds it continues (a collective call; one process: nothing, the cut was entered when it
        was made)."""
        if not self.distributed:
            return
        own = self._pending.pop(gcell, None)
        mine = None
        if own is not None:
            g = self.groups[own[0]]
            sides = self._crossed(g, own[1])
            mine = (sides, self._whole(g.cells[own[1]]).copy(), self._joins(gcell, sides, float(g.wdet[own[1]].sum())))
        held = [v for v in self.exchange.allgather(mine) if v is not None]
        if len(held) != 1:
            raise RuntimeError(f"cell {gcell} is cut on {len(held)} ranks, not one")
        sides, cell_nodes, joins = held[0]
        self._enter(gcell, sides, cell_nodes, joins, own)

    def _joins(self, gcell: int, sides: list, volume: float) -> list[int]:
        """The crack ids of the cut neighbours whose crack crosses a side of cell gcell along the same
        trace (the crack it continues; the cells of a crack given in advance are cut in any order, so
        two of its pieces meet there)."""
        size = volume ** (1.0 / self.dim)
        out = []
        for nodes, trace in sides:
            key = side_key(nodes)
            for other in self.side_cells.get(key, []):
                if other == gcell or other not in self.cut:
                    continue
                for o_nodes, o_trace in self.cut_sides[other]:
                    if side_key(o_nodes) == key and _same_trace(trace, o_trace, 1e-9 * size):
                        out.append(self.cut[other][2])
        return out

    def _enter(self, gcell: int, sides: list, cell_nodes: np.ndarray, joins: list[int],
               own: tuple[int, int] | None) -> None:
        """Enter a cut (sides and nodes by whole mesh id): its crack is a new one, joined to the cracks
        ``joins``. The owner's group keeps the cut's order and crack (checkpointed)."""
        crack = self._new_crack()
        for other in joins:
            self._join(crack, other)
        self.cut[gcell] = (own[0], own[1], crack) if own is not None else (-1, -1, crack)
        self.cut_sides[gcell] = [(tuple(int(v) for v in n), np.asarray(t)) for n, t in sides]
        self.cut_nodes[gcell] = tuple(int(v) for v in cell_nodes)
        if own is not None:
            g = self.groups[own[0]]
            g.cut_serial[own[1]] = len(self.cut_order)
            g.crack_of_cell[own[1]] = crack
        self.cut_order.append(gcell)
        self.dirty = True

    def _new_crack(self) -> int:
        self.parent.append(len(self.parent))
        self.cracks = len(self.parent)
        return len(self.parent) - 1

    def find(self, crack: int) -> int:
        """The crack a crack id belongs to (pieces joined at their meeting points: the smallest id)."""
        while self.parent[crack] != crack:
            self.parent[crack] = self.parent[self.parent[crack]]
            crack = self.parent[crack]
        return crack

    def _join(self, a: int, b: int) -> None:
        ra, rb = self.find(a), self.find(b)
        if ra != rb:
            self.parent[max(ra, rb)] = min(ra, rb)

    def crack_count(self) -> int:
        """How many distinct cracks the cuts make."""
        return len({self.find(c) for c in range(len(self.parent))})

    def restored(self, group) -> None:
        """A group's state came back from a checkpoint; once every group's has, the cuts are taken from
        their cells (each group's ``cut_serial`` and ``crack_of_cell``; on several ranks, every
        rank's: a collective call) in the order they were made."""
        self._restored.add(id(group))
        if len(self._restored) < len(self.groups):
            return
        self._restored.clear()
        mine = []
        for gi, g in enumerate(self.groups):
            for e in np.flatnonzero(g.cut_serial >= 0).tolist():
                mine.append((int(g.cut_serial[e]), int(g.whole_ids[e]), int(g.crack_of_cell[e]), self._crossed(g, e),
                             tuple(int(v) for v in self._whole(g.cells[e])), (gi, e)))
        cuts = sorted((c if k == self.rank else c[:5] + (None,)  # another rank's cut has no owner here
                       for k, part in enumerate(self.exchange.allgather(mine)) for c in part), key=lambda c: c[0])
        self.cut = {gcell: ((own[0], own[1], crack) if own is not None else (-1, -1, crack))
                    for _, gcell, crack, _, _, own in cuts}
        self.cut_sides = {gcell: [(tuple(int(v) for v in n), np.asarray(t)) for n, t in sides]
                          for _, gcell, _, sides, _, _ in cuts}
        self.cut_nodes = {gcell: nodes for _, gcell, _, _, nodes, _ in cuts}
        self.cut_order = [gcell for _, gcell, _, _, _, _ in cuts]
        self.parent = list(range(1 + max((c[2] for c in cuts), default=-1)))  # the groups keep joined ids
        self.cracks = len(self.parent)
        self._pending.clear()
        self.dirty = True
        self.version += 1

    def refresh(self) -> int:
        """Recompute which nodes carry which crack's enrichment (module doc) if a cell was cut since;
        returns the version: it grows at every change, and on several MPI ranks at every new cut (a
        rank decides the nodes of its own cells only, so what changes differs from rank to rank
        where the cuts do not)."""
        if not self.dirty:
            return self.version
        enriched = np.zeros_like(self.enriched)
        crack_of = np.full_like(self.crack_of, -1)
        tips: dict[int, set[int]] = {}  # crack -> nodes of its tip edges
        for gcell in self.cut_order:
            crack = self.find(self.cut[gcell][2])
            for nodes, _ in self.cut_sides[gcell]:
                across = [c for c in self.side_cells.get(side_key(nodes), []) if c != gcell]
                if across and across[0] not in self.cut:
                    tips.setdefault(crack, set()).update(int(v) for v in nodes)
        for gcell in self.cut_order:
            crack = self.find(self.cut[gcell][2])
            for node in self.cut_nodes[gcell]:
                if node in tips.get(crack, ()):
                    continue
                i = int(self.index(np.array(node)))
                if crack_of[i] < 0:
                    crack_of[i] = crack
                    enriched[i] = True
        for g in self.groups:  # the groups keep each cut cell's crack, pieces joined (as checkpointed)
            cut = g.crack_of_cell >= 0
            g.crack_of_cell[cut] = [self.find(int(c)) for c in g.crack_of_cell[cut]]
        changed = not (np.array_equal(enriched, self.enriched) and np.array_equal(crack_of, self.crack_of))
        self.enriched, self.crack_of = enriched, crack_of
        self.dirty = False
        if changed or self.distributed:
            self.version += 1
        return self.version

    def enrichment_of(self, group) -> np.ndarray:
        """(n_el, k) 0/1: where a node of a group's cell carries the enrichment of the cell's own crack
        (cut cells; 0 elsewhere)."""
        idx = self.index(self._whole(group.cells))
        crack_cell = np.array([self.find(int(c)) if c >= 0 else -1 for c in group.crack_of_cell])
        enr = self.enriched[idx] & (self.crack_of[idx] == crack_cell[:, None]) & (crack_cell[:, None] >= 0)
        return enr.astype(float)

    def prescribed(self, dirichlet: np.ndarray) -> np.ndarray:
        """The q's of the prescribed displacement components of the registry's nodes (dirichlet and the
        q's in the model's numbering; an MPI rank's: those of its local dofs)."""
        dirichlet = np.asarray(dirichlet, dtype=np.int64)
        if self.numbering is not None:
            dirichlet = self.numbering.global_(dirichlet)  # on the mesh's (a piece's) nodes
        node, comp = np.divmod(dirichlet, self.dim)
        if self.place is not None:  # the piece's nodes by whole mesh id (none of them: an extra dof)
            mesh_node = node < self.place.nodes.size
            node = np.where(mesh_node, self.place.nodes[np.where(mesh_node, node, 0)], -1)
        i = np.searchsorted(self.nodes, node)
        inside = (i < self.nodes.size)
        inside[inside] = self.nodes[i[inside]] == node[inside]
        q = self.offset + self.dim * i[inside] + comp[inside]
        return q if self.numbering is None else self.numbering.local_part(q)[0]

    # -- loads on a boundary the crack crosses --------------------------------------------------
    def surface_forces(self, sides: np.ndarray, tractions: np.ndarray, n_dofs: int) -> np.ndarray:
        """The q part (n_dofs,) of the nodal forces of tractions [Pa] on boundary sides (m, 2) edges in
        2D, (m, 3|4) faces in 3D (mesh nodes), given at the sides' nodes (m, s, dim) and interpolated
        between them: on a side a crack crosses, node a's q takes (H_other - H_a) times the integral
        of N_a t over the part of the side across the crack from a (the group's :meth:`split_side`);
        the rest is zero."""
        out = np.zeros(n_dofs)
        if not self.cut or sides.size == 0:
            return out
        load = {side_key(nodes): (nodes, tractions[k]) for k, nodes in enumerate(self._whole(sides).tolist())}
        for gcell in self.cut_order:
            gi, e, crack = self.cut[gcell]
            if gi < 0:
                continue  # another rank's cell: its share is that rank's (the model sums them)
            crack = self.find(crack)
            g = self.groups[gi]
            for nodes, _ in self.cut_sides[gcell]:
                key = side_key(nodes)
                if key not in load or len(self.side_cells.get(key, [])) != 1:
                    continue  # not a loaded boundary side
                order, t = load[key]
                at_nodes = t[[order.index(v) for v in nodes]]  # in the order of ``nodes``
                for node, weights in g.split_side(e, self._piece(nodes)).items():
                    i = int(self.index(self._whole(np.array(node))))
                    if not self.enriched[i] or self.crack_of[i] != crack:
                        continue
                    dofs = self._local(self.offset + self.dim * i + np.arange(self.dim))
                    out[dofs] += weights @ at_nodes
        return out


def _same_trace(a: np.ndarray, b: np.ndarray, tol: float) -> bool:
    """Two traces of a crack on a side (points (p, dim)) are the same, in any order."""
    a, b = np.atleast_2d(a), np.atleast_2d(b)
    if a.shape != b.shape:
        return False
    return bool(all(np.min(np.linalg.norm(b - x, axis=1)) <= tol for x in a))
