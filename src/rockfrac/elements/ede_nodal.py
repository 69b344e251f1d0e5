"""Embedded cracks with a nodal jump: the crack cuts its cells into two sides that deform on their own
(shifted Heaviside enrichment of the cut cells' nodes), joined only by the traction of the Sect. 4.1
law on the crack (``[embedded] kinematics = "nodal"``).

The same bifurcation, crack-path tracking and peak cohesion (eq. 28) as the elemental EDE
(rockfrac.elements.ede): a cell is cut where det A = 0 is reached, along the crack path. What the
cut does differs. The elemental EDE keeps one stress field per cut cell and one constant jump,
condensed in the cell; the stress the cell carries along the crack then also crosses it wherever
the crack runs across the cell at a slant (its grad f_S is not along n), which is the stress
locking of a band of such cells (benchmarks/README.md, "Embedded band tracking"). Here the cut
cell's two sides are integrated apart (rockfrac.fem.cut_cell), each with the Drucker-Prager state
it inherits, the jump [[u]] = sum_a N_a q_a is continuous along the crack (the q's are shared by
the cells of a node) and linear in each cell, and the only force across the crack is its traction:
a crack with no strength left carries nothing but its normal compression, on any mesh.

The law is elasto-plastic with penalty stiffnesses kt, kn (rockfrac.laws.embedded_penalty), with a
tension cut-off T_n <= c, starting from the traction the stress had on the crack when its cell was
cut: the crack appears at its peak, and the stress is continuous in time. A cut changes the discrete
system at the committed displacement (the tip edge it opens lets go of the force that held the crack
closed there; the cut cell is integrated anew): the history reports the energy this releases
(E_released) and the energy balance closes with it. 2D (quad4, tri3), one process.
"""

from __future__ import annotations

import numpy as np

from rockfrac.elements import ede_kernel as K
from rockfrac.elements import ede_nodal_kernel as NK
from rockfrac.elements.base import ElementGroup, Evaluation
from rockfrac.elements.ede import EmbeddedDruckerPrager
from rockfrac.elements.ede_enrichment import EnrichmentRegistry
from rockfrac.elements.ede_nodal_parts import CutCells, HeldEnrichment
from rockfrac.elements.plastic_solid import DruckerPragerSolid
from rockfrac.fem.cut_cell import cut_cell, physical_gradients
from rockfrac.fem.loads import quadrature_points
from rockfrac.laws import embedded_penalty as EP
from rockfrac.laws.drucker_prager_params import N_STATE, S_EPS_P, S_MODE
from rockfrac.laws.elastic import isotropic_compliance, strain_energy

SIDE_POINTS = 12  # most side quadrature points of a cut cell (a quadrilateral cut into 3 + 5 corners)
CRACK_POINTS = 3  # the crack's points in a cut cell: its ends and its middle (rockfrac.fem.cut_cell)

#: the arrays of the cut cells, one row each (resized as cells are cut; checkpointed)
CUT_ARRAYS = ("cc_w", "cc_side", "cc_grads", "cc_hnode", "cc_state", "cc_sigma", "cc_shape", "cc_wk", "cc_frame",
              "cc_cp", "cc_edges", "cc_xk", "cc_cell")


class NodalEmbeddedDruckerPrager(EmbeddedDruckerPrager):
    """Drucker-Prager cells that crack along a tracked path, the crack's jump a nodal field (module doc)."""

    checkpoint_attrs = EmbeddedDruckerPrager.checkpoint_attrs + ("cut_slot", "crack_of_cell", "cut_serial")
    tip_events = True  # a crack that grows cell by cell: every tip's onset located (its steps stay short)

    def __init__(self, *args, kt: float, kn: float, **kwargs):
        super().__init__(*args, **kwargs)
        if self.dim != 2:
            raise ValueError("nodal embedded cracks are 2D (quad4, tri3)")
        if self.tracking == "none":
            raise ValueError("nodal embedded cracks need a continuous crack path: tracking 'local' or 'nonlocal'")
        self.kt, self.kn = float(kt), float(kn)
        self.registry: EnrichmentRegistry | None = None
        self.held: HeldEnrichment | None = None  # the first group of a registry adds its unknowns' group
        self.cut_group = CutCells(self)
        n_el, k = self.cells.shape
        self.cut_slot = np.full(n_el, -1, dtype=np.int64)
        self.crack_of_cell = np.full(n_el, -1, dtype=np.int64)
        self.cut_serial = np.full(n_el, -1, dtype=np.int64)  # the order the cells were cut in (the registry's)
        self._masks_version = -1
        self._enr = np.zeros((n_el, k))
        self._allocate(0)
        self._last_d = np.zeros(self.dofs.shape)  # element displacements of the last evaluation
        self._compliance = isotropic_compliance(self.E, self.nu)  # S: eps_e = sigma S (Voigt rows)
        self.crack_work = 0.0  # the traction law's work on the crack (its dissipation) [J]
        self.cut_energy = 0.0  # the stored energy the cuts' re-integration of their cells added [J]

    def _allocate(self, n: int) -> None:
        """Empty cut-cell arrays for n cells."""
        k, m = self.cells.shape[1], SIDE_POINTS
        self.cc_cell = np.zeros(n, dtype=np.int64)
        self.cc_w = np.zeros((n, m))
        self.cc_side = np.zeros((n, m))
        self.cc_grads = np.zeros((n, m, k, 2))
        self.cc_hnode = np.zeros((n, k))
        self.cc_state = np.zeros((n, m, N_STATE))
        self.cc_sigma = np.zeros((n, m, 6))
        self.cc_shape = np.zeros((n, CRACK_POINTS, k))
        self.cc_wk = np.zeros((n, CRACK_POINTS))
        self.cc_frame = np.zeros((n, 2, 2))
        self.cc_cp = np.zeros((n, CRACK_POINTS, EP.N_CP))
        self.cc_edges = np.zeros((n, 2, 2), dtype=np.int64)
        self.cc_xk = np.zeros((n, 2, 2))
        self.cc_trial = self.cc_state.copy()
        self.cc_trial_sigma = self.cc_sigma.copy()
        self.cc_cp_trial = self.cc_cp.copy()

    # -- the enriched unknowns -----------------------------------------------------------------
    def attach(self, registry: EnrichmentRegistry, first: bool) -> None:
        """Share the model's enrichment registry; the first group brings the unknowns' group."""
        self.registry = registry
        if first:
            self.held = HeldEnrichment(registry, self.law.E)

    def companions(self) -> list[ElementGroup]:
        return [self.cut_group] + ([self.held] if self.held is not None else [])

    def enrichment(self) -> np.ndarray:
        """(n_el, k) 0/1: the nodes carrying their cut cell's crack's enrichment (the registry's)."""
        assert self.registry is not None
        version = self.registry.refresh()
        if version != self._masks_version:
            self._enr = self.registry.enrichment_of(self)
            self._masks_version = version
        return self._enr

    # -- cutting a cell ---------------------------------------------------------------------------
    def localize_cell(self, e: int, normal: np.ndarray, c_p: float | None = None,
                      point: np.ndarray | None = None) -> float:
        """Cut cell e as the elemental EDE does (its surface, + side, c_p of eq. 28), then split it into
        its two sides' quadrature and the crack's three points (module doc)."""
        c_p = super().localize_cell(e, normal, c_p, point)
        s = self.e_state[e]
        n, t = s[K.E_N:K.E_N + 2], s[K.E_T:K.E_T + 2]
        xe = self.x[e]
        cc = cut_cell(self.ref, xe, self.anchor[e, :2], n)
        m = cc.weights.size
        if m > SIDE_POINTS:
            raise RuntimeError(f"cell {e}: {m} side points, more than {SIDE_POINTS}")
        slot = self.cc_w.shape[0]
        old = {name: getattr(self, name) for name in CUT_ARRAYS}
        self._allocate(slot + 1)
        for name, arr in old.items():
            getattr(self, name)[:slot] = arr
        self.cc_trial[:slot], self.cc_trial_sigma[:slot] = self.cc_state[:slot], self.cc_sigma[:slot]
        self.cc_cp_trial[:slot] = self.cc_cp[:slot]
        self.cc_cell[slot] = e
        self.cc_w[slot, :m] = cc.weights
        self.cc_side[slot, :m] = cc.side
        self.cc_grads[slot, :m] = physical_gradients(self.ref, xe, cc.xi)
        self.cc_hnode[slot] = self.active[e]
        # each side point takes the committed state of its nearest Gauss point, with the plastic strain
        # that gives that point's stress at the side point's strain (the cut changes no stress); every
        # crack point the traction of the cell's mean stress (eq. 28, as the elemental EDE: q, P, c_p)
        gauss = quadrature_points(self.nodes, self.cells[e:e + 1], self.ref)[0]  # (n_qp, 2)
        nearest = np.argmin(np.linalg.norm(cc.x[:, None, :] - gauss[None, :, :], axis=2), axis=1)
        sigma = self.sigma[e, nearest]
        self.cc_state[slot, :m] = self.state[e, nearest]
        self.cc_state[slot, :m, S_MODE] = 0.0
        strain = self._strains_at(e, self.cc_grads[slot, :m])
        self.cc_state[slot, :m, S_EPS_P:S_EPS_P + 6] = strain - sigma @ self._compliance
        self.cc_sigma[slot, :m] = sigma
        self.cut_energy += (strain_energy(sigma, self.cc_w[slot, :m], self.E, self.nu)
                            - strain_energy(self.sigma[e], self.wdet[e], self.E, self.nu))
        self.cc_shape[slot] = self.ref.shape(cc.crack_xi)
        self.cc_wk[slot] = cc.crack_weights
        self.cc_frame[slot, 0], self.cc_frame[slot, 1] = t, n
        for k in range(CRACK_POINTS):
            self.cc_cp[slot, k] = EP.initial_state(s[K.E_Q], s[K.E_P], c_p)
        k_nodes = self.cells.shape[1]
        self.cc_edges[slot] = [[self.cells[e, a], self.cells[e, (a + 1) % k_nodes]] for a in cc.crack_edges]
        self.cc_xk[slot] = cc.crack_x[[0, -1]]
        self.cc_trial[slot], self.cc_trial_sigma[slot] = self.cc_state[slot], self.cc_sigma[slot]
        self.cc_cp_trial[slot] = self.cc_cp[slot]
        self.cut_slot[e] = slot
        if self.registry is not None:
            self.cut_serial[e] = len(self.registry.cut_order)
            self.crack_of_cell[e] = self.registry.register_cut(self, e, self.crack_end_edges(e),
                                                               self.crack_end_points(e))
        return c_p

    def _strains_at(self, e: int, grads: np.ndarray) -> np.ndarray:
        """Voigt strains (m, 6) of cell e's displacements of the last evaluation (the committed ones at a
        commit) at points with shape gradients grads (m, k, 2) (plane strain, engineering shear)."""
        d = self._last_d[e].reshape(-1, 2)
        gu = np.einsum("pai,aj->pij", grads, d)  # d u_j / d x_i
        out = np.zeros((grads.shape[0], 6))
        out[:, 0], out[:, 1], out[:, 3] = gu[:, 0, 0], gu[:, 1, 1], gu[:, 0, 1] + gu[:, 1, 0]
        return out

    def crack_end_edges(self, e: int) -> list[tuple[int, int]]:
        """The two cell edges (pairs of mesh nodes) where the crack of cut cell e ends."""
        return [(int(a), int(b)) for a, b in self.cc_edges[self.cut_slot[e]]]

    def crack_end_points(self, e: int) -> np.ndarray:
        """The crack's two end points (2, 2) [m] in cut cell e (on :meth:`crack_end_edges`)."""
        return self.cc_xk[self.cut_slot[e]]

    def node_sides(self, e: int) -> dict[int, float]:
        """H of each node of cut cell e: 1 on the crack's + side, 0 on the other."""
        return {int(a): float(h) for a, h in zip(self.cells[e], self.active[e])}

    # -- the discrete equations ---------------------------------------------------------------
    def begin_step(self) -> None:
        super().begin_step()
        self.cc_trial[:] = self.cc_state
        self.cc_trial_sigma[:] = self.cc_sigma
        self.cc_cp_trial[:] = self.cc_cp

    def evaluate(self, u: np.ndarray, u_n: np.ndarray) -> Evaluation:
        """The uncut cells (Drucker-Prager); a cut cell's blocks are its :class:`CutCells` group's."""
        fe, ke = self.element_buffers()
        self._last_d = np.ascontiguousarray(u[self.dofs])  # (the strains of a cell cut at the commit)
        NK.uncut_blocks(self.grads, self.wdet, self._last_d, self.state, self.p, self.cut_slot,
                        self.trial, self.trial_sigma, fe, ke, self.status)
        bad = np.flatnonzero(self.status < 0)
        msg = f"Drucker-Prager return failed in cells {bad[:5].tolist()} (no admissible return)" if bad.size else ""
        return Evaluation(fe, ke, ok=not bad.size, message=msg)

    def commit(self) -> None:
        DruckerPragerSolid.commit(self)  # the uncut cells' Gauss points (a cut cell's are held)
        if self.cc_w.shape[0]:
            d_eps = self.cc_trial[..., S_EPS_P:S_EPS_P + 6] - self.cc_state[..., S_EPS_P:S_EPS_P + 6]
            self.dissipated += float(0.5 * np.einsum("cpi,cpi,cp->", self.cc_sigma + self.cc_trial_sigma, d_eps,
                                                     self.cc_w))
            d_jp = self.cc_cp_trial[..., EP.CP_JP:EP.CP_JP + 2] - self.cc_cp[..., EP.CP_JP:EP.CP_JP + 2]
            t_mean = 0.5 * (self.cc_cp[..., EP.CP_T:EP.CP_T + 2] + self.cc_cp_trial[..., EP.CP_T:EP.CP_T + 2])
            work = float(np.einsum("cki,cki,ck->", t_mean, d_jp, self.cc_wk))
            self.crack_work += work
            self.crack_dissipated += work
            self.surface_dissipated += work
            self.dissipated += work
            self.cc_state[:] = self.cc_trial
            self.cc_sigma[:] = self.cc_trial_sigma
            self.cc_cp[:] = self.cc_cp_trial
            self._summarize()
        self.e_trial[:] = self.e_state
        self.last_event = self._localize()

    def _summarize(self) -> None:
        """The cut cells' per-cell records (e_state) and Gauss-point stresses (for output): the means
        over their crack points and side points."""
        cells = self.cc_cell
        cp = self.cc_cp
        st = self.e_state
        frame = self.cc_frame
        along = self.cc_wk / self.cc_wk.sum(axis=1, keepdims=True)  # means along each cell's crack

        def mean(slot: int) -> np.ndarray:
            return np.einsum("ck,ck->c", along, cp[..., slot])

        j_loc = np.column_stack([mean(EP.CP_J), mean(EP.CP_J + 1)])  # (c, 2) in (t, n)
        st[cells, K.E_J:K.E_J + 2] = j_loc[:, :1] * frame[:, 0] + j_loc[:, 1:] * frame[:, 1]
        st[cells, K.E_Q] = mean(EP.CP_T)
        st[cells, K.E_P] = mean(EP.CP_T + 1)
        st[cells, K.E_GAMMA] = mean(EP.CP_GAMMA)
        st[cells, K.E_ZETA] = mean(EP.CP_ZETA)
        st[cells, K.E_DZETA] = mean(EP.CP_DZ)
        st[cells, K.E_MODE] = (cp[..., EP.CP_MODE] > 0.0).any(axis=1)  # 1: a point flowed in the step
        # the slip sense: the slide's so far (a crack with no strength left has no shear to tell it)
        slip = mean(EP.CP_JP)
        slid = slip != 0.0
        st[cells[slid], K.E_SIGN] = np.sign(slip[slid])
        loaded = ~slid & (st[cells, K.E_Q] != 0.0)
        st[cells[loaded], K.E_SIGN] = np.sign(st[cells[loaded], K.E_Q])
        w = self.cc_w / self.cc_w.sum(axis=1, keepdims=True)
        self.sigma[cells] = np.einsum("cp,cpi->ci", w, self.cc_sigma)[:, None, :]
        self.state[cells] = np.einsum("cp,cps->cs", w, self.cc_state)[:, None, :]
        self.state[cells, :, S_MODE] = 0.0

    # -- output and energy ---------------------------------------------------------------------
    def elastic_energy(self, u: np.ndarray) -> float:
        """The uncut cells', the cut cells' sides' and the crack's stored energy [J] (per unit thickness):
        T0 . j_e + j_e K j_e / 2 at a crack point, j_e = j - J_p its elastic jump."""
        uncut = self.cut_slot < 0
        bulk = strain_energy(self.sigma[uncut], self.wdet[uncut], self.E, self.nu)
        if not self.cc_w.shape[0]:
            return bulk
        sides = strain_energy(self.cc_sigma, self.cc_w, self.E, self.nu)
        cp = self.cc_cp
        je = cp[..., EP.CP_J:EP.CP_J + 2] - cp[..., EP.CP_JP:EP.CP_JP + 2]
        t0 = cp[..., EP.CP_T0:EP.CP_T0 + 2]
        crack = np.einsum("cki,cki->ck", t0, je) + 0.5 * (self.kt * je[..., 0] ** 2 + self.kn * je[..., 1] ** 2)
        return bulk + sides + float(np.sum(crack * self.cc_wk))

    def recut_energy(self) -> float:
        return self.cut_energy

    # -- checkpoints -----------------------------------------------------------------------------
    def checkpoint_state(self) -> dict[str, np.ndarray]:
        out = super().checkpoint_state()
        for name in CUT_ARRAYS:
            out[name] = np.array(getattr(self, name))
        out["crack_work"] = np.array(self.crack_work)
        out["cut_energy"] = np.array(self.cut_energy)
        return out

    def restore_checkpoint(self, saved: dict[str, np.ndarray]) -> None:
        missing = [n for n in CUT_ARRAYS if n not in saved]
        if missing:
            raise ValueError(f"the checkpoint has no {type(self).__name__}.{missing[0]}: a different model")
        n = saved["cc_w"].shape[0]
        self._allocate(n)
        for name in CUT_ARRAYS:
            if saved[name].shape != getattr(self, name).shape:
                raise ValueError(f"the checkpoint was written for a different model ({name})")
            getattr(self, name)[...] = saved[name]
        self.cc_trial[:], self.cc_trial_sigma[:], self.cc_cp_trial[:] = self.cc_state, self.cc_sigma, self.cc_cp
        super().restore_checkpoint(saved)
        self.crack_work = float(saved["crack_work"])
        self.cut_energy = float(saved["cut_energy"]) if "cut_energy" in saved else 0.0
        if self.registry is not None:
            self.registry.restored(self)
