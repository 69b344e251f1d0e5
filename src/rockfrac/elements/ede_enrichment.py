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


def edge_key(a: int, b: int) -> tuple[int, int]:
    return (a, b) if a < b else (b, a)


class EnrichmentRegistry:
    """The enriched unknowns of a model's nodal-crack groups (module doc).

    groups: the groups (each with ``cells`` (n_el, k) mesh nodes and ``cell_ids`` their mesh cells);
    mesh_cells: every cell of the 2D mesh (n, k) (the neighbours across crack-tip edges).
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
        self.edge_cells: dict[tuple[int, int], list[int]] = {}
        k = mesh_cells.shape[1]
        for c, conn in enumerate(mesh_cells.tolist()):
            for a in range(k):
                self.edge_cells.setdefault(edge_key(conn[a], conn[(a + 1) % k]), []).append(c)
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
    def register_cut(self, group, local: int, end_edges: list[tuple[int, int]], end_points: np.ndarray) -> int:
        """A cell of ``group`` has been cut; its crack's ends lie on the edges ``end_edges`` (pairs of
        mesh nodes) at ``end_points`` (2, 2) [m]. Returns its crack: a new one, joined to that of every
        cut neighbour whose crack ends at the same point of a shared edge (the crack it continues; the
        cells of a crack given in advance are cut in any order, so two of its pieces meet there)."""
        gcell = int(group.cell_ids[local])
        crack = self._new_crack()
        size = float(np.sqrt(group.wdet[local].sum()))
        for (a, b), x in zip(end_edges, end_points):
            for other in self.edge_cells.get(edge_key(a, b), []):
                if other == gcell or other not in self.cut:
                    continue
                gi, e, other_crack = self.cut[other]
                g = self.groups[gi]
                for pair, y in zip(g.crack_end_edges(e), g.crack_end_points(e)):
                    if edge_key(*pair) == edge_key(a, b) and np.linalg.norm(y - x) <= 1e-9 * size:
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
            for a, b in g.crack_end_edges(e):
                across = [c for c in self.edge_cells.get(edge_key(a, b), []) if c != gcell]
                if across and across[0] not in self.cut:
                    tips.setdefault(crack, set()).update((a, b))
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
    def surface_forces(self, edges: np.ndarray, tractions: np.ndarray, n_dofs: int) -> np.ndarray:
        """The q part (n_dofs,) of the nodal forces of uniform tractions (m, 2) [Pa] on boundary edges
        (m, 2) (mesh nodes): on an edge a crack crosses at s (from node a, 0..1), node a's q takes
        (H_other - H_a) t L times the integral of N_a over the other side; the rest is zero."""
        out = np.zeros(n_dofs)
        if not self.cut or edges.size == 0:
            return out
        load = {edge_key(int(a), int(b)): tractions[k] for k, (a, b) in enumerate(edges.tolist())}
        for gcell in self.cut_order:
            gi, e, crack = self.cut[gcell]
            crack = self.find(crack)
            g = self.groups[gi]
            for (a, b), x in zip(g.crack_end_edges(e), g.crack_end_points(e)):
                key = edge_key(a, b)
                if key not in load or len(self.edge_cells.get(key, [])) != 1:
                    continue  # not a loaded boundary edge
                xa, xb = g.nodes[a, :2], g.nodes[b, :2]
                length = float(np.linalg.norm(xb - xa))
                s = float(np.dot(x - xa, xb - xa)) / length ** 2
                side = g.node_sides(e)
                h = {a: side[a], b: side[b]}
                for node, part in ((a, 0.5 * (1.0 - s) ** 2), (b, 0.5 * s ** 2)):
                    i = int(self.index(np.array(node)))
                    if not self.enriched[i] or self.crack_of[i] != crack:
                        continue
                    other = 1.0 - h[node]  # the side across the crack from the node
                    dofs = self.offset + self.dim * i + np.arange(self.dim)
                    out[dofs] += (other - h[node]) * part * length * load[key]
        return out
