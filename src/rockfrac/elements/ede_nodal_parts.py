"""The two element groups a nodal embedded crack adds to the model beside its Drucker-Prager cells
(rockfrac.elements.ede_nodal): the cut cells, on their nodes' displacements and enrichments, and the
enrichment unknowns themselves, held at zero where no crack has reached.

Only cut cells couple the enrichments, so the global matrix grows with the cracks, not with the
region that may crack: the cut cells' group gains a row at every cut, and the model makes its
sparsity pattern again (:meth:`rockfrac.elements.base.ElementGroup.structure_version`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from rockfrac.elements import ede_nodal_kernel as NK
from rockfrac.elements.base import ElementGroup, Evaluation
from rockfrac.elements.ede_enrichment import EnrichmentRegistry

if TYPE_CHECKING:
    from rockfrac.elements.ede_nodal import NodalEmbeddedDruckerPrager


class CutCells(ElementGroup):
    """The cut cells of a nodal embedded-crack group: each side's Drucker-Prager points and the crack's
    traction, on (u, q) of the cell's nodes (rockfrac.elements.ede_nodal_kernel.cut_blocks). Their
    state lives in the owning group, which commits it."""

    def __init__(self, owner: NodalEmbeddedDruckerPrager):
        self.owner = owner
        self.name = f"{owner.name} (cut cells)"
        self._dofs = np.zeros((0, 2 * owner.dim * owner.cells.shape[1]), dtype=np.int64)
        self._key: tuple[int, int] = (-1, -1)

    @property
    def dofs(self) -> np.ndarray:  # type: ignore[override]
        """(n_cut, 4 k): the cut cells' u's, then their nodes' q's."""
        g = self.owner
        assert g.registry is not None
        key = (g.cc_cell.size, g.registry.offset)
        if key != self._key:
            cells = g.cc_cell
            self._dofs = np.hstack([g.dofs[cells], g.registry.dofs(g.cells[cells])]).astype(np.int64)
            self._key = key
        return self._dofs

    def reach(self) -> np.ndarray:
        """The u's and q's of every cell of the owner, each of which a crack may cut."""
        g = self.owner
        assert g.registry is not None
        return np.concatenate([g.dofs.ravel(), g.registry.dofs(g.cells).ravel()])

    def renumber(self, numbering) -> None:
        """The owner and the registry are renumbered by themselves; the cut cells' dofs are made again."""
        self._key = (-1, -1)

    def structure_version(self) -> int:
        """The number of cut cells (a new one is new rows of the matrix)."""
        return int(self.owner.cc_cell.size)

    def checkpoint_state(self) -> dict[str, np.ndarray]:
        return {"cut_cells": np.array(self.owner.cc_cell.size)}  # the state is the owner's

    def restore_checkpoint(self, saved: dict[str, np.ndarray]) -> None:
        if "cut_cells" not in saved or int(saved["cut_cells"]) != self.owner.cc_cell.size:
            raise ValueError("the checkpoint was written for a different model (cut cells)")

    def evaluate(self, u: np.ndarray, u_n: np.ndarray) -> Evaluation:
        g = self.owner
        n, nd = self.dofs.shape
        fe, ke = np.empty((n, nd)), np.empty((n, nd, nd))
        status = np.zeros(n, dtype=np.int64)
        if n:
            enr = g.enrichment()
            blocks = NK.cut_blocks if g.dim == 2 else NK.cut_blocks_3d
            blocks(np.ascontiguousarray(u[self.dofs]), np.ascontiguousarray(enr[g.cc_cell]), g.cc_w, g.cc_side,
                   g.cc_grads, g.cc_hnode, g.cc_state, g.cc_shape, g.cc_wk, g.cc_frame, g.cc_cp, g.p,
                   g.surface_params, g.kt, g.kn, g.cc_trial, g.cc_trial_sigma, g.cc_cp_trial, fe, ke, status)
        bad = np.flatnonzero(status < 0)
        if not bad.size:
            return Evaluation(fe, ke)
        why = {NK.ST_DP_FAIL: "no Drucker-Prager return on a side", NK.ST_CRACK_FAIL: "no return of the crack's law"}
        cells = g.whole_ids[g.cc_cell[bad[:5]]].tolist()
        return Evaluation(fe, ke, ok=False, message=f"cut cells {cells}: {why[int(status[bad[0]])]}")


class HeldEnrichment(ElementGroup):
    """The enrichment unknowns of a model's nodal cracks (two per node of their groups, owned here):
    k0 q = 0 on those of the nodes that carry no crack's enrichment, nothing on the others (their
    equations are the cut cells'). k0 [N/m] only scales the held rows."""

    def __init__(self, registry: EnrichmentRegistry, k0: float):
        self.registry = registry
        self.k0 = float(k0)
        self.name = "enrichment"
        self.n_extra = registry.size
        self.rows = np.arange(registry.size, dtype=np.int64)  # the q's held here (on an MPI rank: its own)
        self.dofs = self.rows[:, None].copy()

    def hold_only(self, nodes: np.ndarray) -> None:
        """Hold the q's of these registry nodes only (an MPI rank's: those of the nodes it owns)."""
        d = self.registry.dim
        self.rows = (d * np.asarray(nodes, dtype=np.int64)[:, None] + np.arange(d)).ravel()
        self.n_extra = self.rows.size
        self.dofs = self.registry.offset + self.rows[:, None]

    def extra_span(self) -> int:
        return self.registry.size  # numbered over every node of the registry, on every rank

    def set_offset(self, offset: int) -> None:
        self.registry.set_offset(offset)
        self.dofs = offset + self.rows[:, None]

    def renumber(self, numbering) -> None:
        """The held q's, and every q the registry numbers from now on, in the rank's local numbering."""
        self.registry.numbering = numbering
        self.dofs = numbering.local(self.dofs)

    def structure_version(self) -> int:
        """The cuts made so far, any rank's: the same on every rank, so that a distributed model
        makes its matrix again on all of them at once."""
        return len(self.registry.cut_order)

    def redundant_extras(self, dirichlet: np.ndarray) -> np.ndarray:
        """The q's of prescribed displacement components (a crack does not open across a support)."""
        return self.registry.prescribed(dirichlet)

    def checkpoint_state(self) -> dict[str, np.ndarray]:
        return {"unknowns": np.array(self.registry.size)}  # the cuts are the groups' (the registry's restored)

    def restore_checkpoint(self, saved: dict[str, np.ndarray]) -> None:
        if "unknowns" not in saved or int(saved["unknowns"]) != self.registry.size:
            raise ValueError("the checkpoint was written for a different model (enrichment unknowns)")

    def evaluate(self, u: np.ndarray, u_n: np.ndarray) -> Evaluation:
        held = ~np.repeat(self.registry.enriched, self.registry.dim)[self.rows]
        k = np.where(held, self.k0, 0.0)
        return Evaluation((k * u[self.dofs[:, 0]])[:, None], k[:, None, None])

    def enrichment_version(self) -> int:
        return self.registry.refresh()

    def enriched_surface_forces(self, edges: np.ndarray, tractions: np.ndarray, n_dofs: int) -> np.ndarray:
        return self.registry.surface_forces(edges, tractions, n_dofs)
