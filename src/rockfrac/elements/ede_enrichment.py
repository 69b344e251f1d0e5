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
"""

from __future__ import annotations

import numpy as np


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

    groups: the groups (each with ``cells`` (n_el, k) mesh nodes and ``cell_ids`` their mesh cells);
    mesh_cells: every cell of the mesh (n, k) (the neighbours across crack-tip sides). A group tells
    where its cut cell e's crack crosses the cell's sides: ``crossed_sides(e)``, a list of (side's
    mesh nodes, the crack's trace on it: its end point in 2D, its segment on the face in 3D).
    """

    def __init__(self, groups: list, mesh_cells: np.ndarray, dim: int = 2):
        self.groups = groups
        self.dim = dim
        self.nodes = np.unique(np.concatenate([g.cells.ravel() for g in groups]))
        self.offset = 0
        self.enriched = np.zeros(self.nodes.size, dtype=bool)
        self.crack_of = np.full(self.nodes.size, -1)
        self.version = 0
        self.dirty = False
        self.side_cells: dict[tuple[int, ...], list[int]] = {}
        local = cell_sides(mesh_cells, dim)
        for c, conn in enumerate(mesh_cells.tolist()):
            for side in local:
                self.side_cells.setdefault(side_key(conn[a] for a in side), []).append(c)
        self.cut: dict[int, tuple[int, int, int]] = {}  # mesh cell -> (group, local cell, crack id)
        self.cut_order: list[int] = []
        self.parent: list[int] = []  # crack ids joined into cracks (union-find)
        self.cracks = 0
        self._restored: set[int] = set()

    # -- numbering ----------------------------------------------------------------------------
    @property
    def size(self) -> int:
        """The number of enriched unknowns (every node, every direction)."""
        return self.dim * self.nodes.size

    def index(self, nodes: np.ndarray) -> np.ndarray:
        """The registry's index of mesh nodes (any shape)."""
        return np.searchsorted(self.nodes, nodes)

    def dofs(self, cells: np.ndarray) -> np.ndarray:
        """The q unknowns (n_el, dim k) of cells (n_el, k) of mesh nodes, node by node."""
        i = self.index(cells)
        q = self.offset + self.dim * i[..., None] + np.arange(self.dim)
        return q.reshape(cells.shape[0], self.dim * cells.shape[1])

    def set_offset(self, offset: int) -> None:
        """Number the q's from ``offset``."""
        self.offset = offset
        self.version += 1  # the cut cells' dofs change with it

    # -- the cuts ------------------------------------------------------------------------------
    def register_cut(self, group, local: int) -> int:
        """A cell of ``group`` has been cut. Returns its crack: a new one, joined to that of every cut
        neighbour whose crack crosses a shared side along the same trace (the crack it continues; the
        cells of a crack given in advance are cut in any order, so two of its pieces meet there)."""
        gcell = int(group.cell_ids[local])
        crack = self._new_crack()
        size = float(group.wdet[local].sum()) ** (1.0 / self.dim)
        for nodes, trace in group.crossed_sides(local):
            key = side_key(nodes)
            for other in self.side_cells.get(key, []):
                if other == gcell or other not in self.cut:
                    continue
                gi, e, other_crack = self.cut[other]
                for o_nodes, o_trace in self.groups[gi].crossed_sides(e):
                    if side_key(o_nodes) == key and _same_trace(trace, o_trace, 1e-9 * size):
                        self._join(crack, other_crack)
        self.cut[gcell] = (self.groups.index(group), local, crack)
        self.cut_order.append(gcell)
        self.dirty = True
        return crack

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
        their cells (each group's ``cut_serial`` and ``crack_of_cell``) in the order they were made."""
        self._restored.add(id(group))
        if len(self._restored) < len(self.groups):
            return
        self._restored.clear()
        cuts = []
        for gi, g in enumerate(self.groups):
            for e in np.flatnonzero(g.cut_serial >= 0).tolist():
                cuts.append((int(g.cut_serial[e]), int(g.cell_ids[e]), gi, e, int(g.crack_of_cell[e])))
        cuts.sort()
        self.cut = {gcell: (gi, e, crack) for _, gcell, gi, e, crack in cuts}
        self.cut_order = [gcell for _, gcell, _, _, _ in cuts]
        self.parent = list(range(1 + max((c[4] for c in cuts), default=-1)))  # the groups keep joined ids
        self.cracks = len(self.parent)
        self.dirty = True
        self.version += 1

    def refresh(self) -> int:
        """Recompute which nodes carry which crack's enrichment (module doc) if a cell was cut since;
        returns the version (it grows at every change)."""
        if not self.dirty:
            return self.version
        enriched = np.zeros_like(self.enriched)
        crack_of = np.full_like(self.crack_of, -1)
        tips: dict[int, set[int]] = {}  # crack -> nodes of its tip edges
        for gcell in self.cut_order:
            gi, e, crack = self.cut[gcell]
            crack = self.find(crack)
            g = self.groups[gi]
            for nodes, _ in g.crossed_sides(e):
                across = [c for c in self.side_cells.get(side_key(nodes), []) if c != gcell]
                if across and across[0] not in self.cut:
                    tips.setdefault(crack, set()).update(int(v) for v in nodes)
        for gcell in self.cut_order:
            gi, e, crack = self.cut[gcell]
            crack = self.find(crack)
            g = self.groups[gi]
            for node in g.cells[e].tolist():
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
        if changed:
            self.version += 1
        return self.version

    def enrichment_of(self, group) -> np.ndarray:
        """(n_el, k) 0/1: where a node of a group's cell carries the enrichment of the cell's own crack
        (cut cells; 0 elsewhere)."""
        idx = self.index(group.cells)
        crack_cell = np.array([self.find(int(c)) if c >= 0 else -1 for c in group.crack_of_cell])
        enr = self.enriched[idx] & (self.crack_of[idx] == crack_cell[:, None]) & (crack_cell[:, None] >= 0)
        return enr.astype(float)

    def prescribed(self, dirichlet: np.ndarray) -> np.ndarray:
        """The q's of the prescribed displacement components of the registry's nodes."""
        node, comp = np.divmod(np.asarray(dirichlet, dtype=np.int64), self.dim)
        i = np.searchsorted(self.nodes, node)
        inside = (i < self.nodes.size)
        inside[inside] = self.nodes[i[inside]] == node[inside]
        return self.offset + self.dim * i[inside] + comp[inside]

    # -- loads on a boundary the crack crosses --------------------------------------------------
    def surface_forces(self, sides: np.ndarray, tractions: np.ndarray, n_dofs: int) -> np.ndarray:
        """The q part (n_dofs,) of the nodal forces of tractions [Pa] on boundary sides (m, 2) edges in
        2D, (m, 3|4) faces in 3D (mesh nodes), uniform per side (m, dim) or at the side's nodes (m, s,
        dim), interpolated between them: on a side a crack crosses, node a's q takes (H_other - H_a)
        times the integral of N_a t over the part of the side across the crack from a (the group's
        :meth:`split_side`); the rest is zero."""
        out = np.zeros(n_dofs)
        if not self.cut or sides.size == 0:
            return out
        load = {side_key(nodes): (nodes, tractions[k]) for k, nodes in enumerate(sides.tolist())}
        for gcell in self.cut_order:
            gi, e, crack = self.cut[gcell]
            crack = self.find(crack)
            g = self.groups[gi]
            for nodes, _ in g.crossed_sides(e):
                key = side_key(nodes)
                if key not in load or len(self.side_cells.get(key, [])) != 1:
                    continue  # not a loaded boundary side
                order, t = load[key]
                at_nodes = (np.broadcast_to(t, (len(nodes), self.dim)) if t.ndim == 1
                            else t[[order.index(v) for v in nodes]])  # in the order of ``nodes``
                for node, weights in g.split_side(e, nodes).items():
                    i = int(self.index(np.array(node)))
                    if not self.enriched[i] or self.crack_of[i] != crack:
                        continue
                    dofs = self.offset + self.dim * i + np.arange(self.dim)
                    out[dofs] += weights @ at_nodes
        return out


def _same_trace(a: np.ndarray, b: np.ndarray, tol: float) -> bool:
    """Two traces of a crack on a side (points (p, dim)) are the same, in any order."""
    a, b = np.atleast_2d(a), np.atleast_2d(b)
    if a.shape != b.shape:
        return False
    return bool(all(np.min(np.linalg.norm(b - x, axis=1)) <= tol for x in a))
