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
(E_released) and the energy balance closes with it.

In a general 3D body (tet4, hex8) the crack is a plane in each cell (its polygon the crack's
quadrature, rockfrac.fem.cut_cell.cut_cell_3d) and the law acts isotropically in that plane
(rockfrac.laws.embedded_penalty.crack_return_3d); a crack continued from a cut neighbour stays in
that neighbour's plane (a 3D nodal crack grows in its plane), so that neighbouring cells share the
crack's trace on their common face. On several MPI ranks the enrichment registry is the same on
every rank (rockfrac.elements.ede_enrichment: cuts announced in the serial order).
"""

from __future__ import annotations

import math

import numpy as np

from rockfrac.elements import ede_kernel as K
from rockfrac.elements import ede_nodal_kernel as NK
from rockfrac.elements.base import ElementGroup, Evaluation
from rockfrac.elements.ede import EmbeddedDruckerPrager
from rockfrac.elements.ede_enrichment import EnrichmentRegistry
from rockfrac.elements.ede_nodal_parts import CutCells, HeldEnrichment
from rockfrac.elements.plastic_solid import DruckerPragerSolid
from rockfrac.fem.cut_cell import FACES, TRIANGLE_RULE_6, clip_by, cut_cell, cut_cell_3d, inverse_map, physical_gradients
from rockfrac.fem.loads import StressField, quadrature_points
from rockfrac.laws import embedded_penalty as EP
from rockfrac.laws.drucker_prager_params import N_STATE, S_EPS_P, S_MODE
from rockfrac.laws.elastic import isotropic_compliance, strain_energy
from rockfrac.laws.mohr_coulomb_softening import strengths

#: the most quadrature points of a cut cell (rockfrac.fem.cut_cell): its sides' and its crack's, and
#: the sides of the cell the crack crosses (edges in 2D, faces in 3D), by cell type
SIDE_POINTS = {"quad4": 12, "tri3": 12, "tet4": 2, "hex8": 512}
CRACK_POINTS = {"quad4": 3, "tri3": 3, "tet4": 12, "hex8": 36}
CROSSED = {"quad4": (2, 2, 1), "tri3": (2, 2, 1), "tet4": (4, 3, 2), "hex8": (6, 4, 2)}  # sides, nodes, trace

#: the arrays of the cut cells, one row each (resized as cells are cut; checkpointed)
CUT_ARRAYS = ("cc_w", "cc_side", "cc_grads", "cc_nside", "cc_hnode", "cc_state", "cc_sigma", "cc_shape", "cc_wk",
              "cc_frame", "cc_cp", "cc_sides", "cc_traces", "cc_cell")


class NodalEmbeddedDruckerPrager(EmbeddedDruckerPrager):
    """Drucker-Prager cells that crack along a tracked path, the crack's jump a nodal field (module doc)."""

    checkpoint_attrs = EmbeddedDruckerPrager.checkpoint_attrs + ("cut_slot", "crack_of_cell", "cut_serial")
    tip_events = True  # a crack that grows cell by cell: every tip's onset located (its steps stay short)

    def __init__(self, *args, kt: float, kn: float, **kwargs):
        super().__init__(*args, **kwargs)
        if self.dim == 3 and self.plane_strain:
            raise ValueError("nodal embedded cracks are for 2D meshes and general 3D bodies, not a plane-strain slab")
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
        self._sigma0: StressField | None = None  # the in-situ stress field (its variation inside a cut cell)
        self.crack_work = 0.0  # the traction law's work on the crack (its dissipation) [J]
        self.cut_energy = 0.0  # the stored energy the cuts' re-integration of their cells added [J]
        # the crack points' state slots (rockfrac.laws.embedded_penalty), in 2D or 3D
        if self.dim == 2:
            self._slot = dict(T0=EP.CP_T0, JP=EP.CP_JP, T=EP.CP_T, J=EP.CP_J, GAMMA=EP.CP_GAMMA,
                              ZETA=EP.CP_ZETA, MODE=EP.CP_MODE, DZ=EP.CP_DZ)
        else:
            self._slot = dict(T0=EP.C3_T0, JP=EP.C3_JP, T=EP.C3_T, J=EP.C3_J, GAMMA=EP.C3_GAMMA,
                              ZETA=EP.C3_ZETA, MODE=EP.C3_MODE, DZ=EP.C3_DZ)

    def _allocate(self, n: int) -> None:
        """Empty cut-cell arrays for n cells."""
        k, m, dim, name = self.cells.shape[1], SIDE_POINTS[self.ref.name], self.dim, self.ref.name
        points = CRACK_POINTS[name]
        n_sides, side_nodes, trace = CROSSED[name]
        self.cc_cell = np.zeros(n, dtype=np.int64)
        self.cc_w = np.zeros((n, m))
        self.cc_side = np.zeros((n, m))
        self.cc_grads = np.zeros((n, m, k, dim))
        self.cc_nside = np.zeros((n, m, k))  # the shape values at the side points
        self.cc_hnode = np.zeros((n, k))
        self.cc_state = np.zeros((n, m, N_STATE))
        self.cc_sigma = np.zeros((n, m, 6))
        self.cc_shape = np.zeros((n, points, k))
        self.cc_wk = np.zeros((n, points))
        self.cc_frame = np.zeros((n, dim, dim))
        self.cc_cp = np.zeros((n, points, EP.N_CP if dim == 2 else EP.N_C3))
        self.cc_sides = np.full((n, n_sides, side_nodes), -1, dtype=np.int64)  # the sides the crack crosses
        self.cc_traces = np.full((n, n_sides, trace, dim), np.nan)  # the crack's trace on each [m]
        self.cc_trial = self.cc_state.copy()
        self.cc_trial_sigma = self.cc_sigma.copy()
        self.cc_cp_trial = self.cc_cp.copy()

    # -- the enriched unknowns -----------------------------------------------------------------
    def attach(self, registry: EnrichmentRegistry, first: bool) -> None:
        """Share the model's enrichment registry; the first group brings the unknowns' group."""
        self.registry = registry
        if first:
            self.held = HeldEnrichment(registry, self.law.E)

    def align_slip(self) -> None:
        """A 3D nodal crack's frame stays as cut (its law is isotropic in its plane)."""

    def slip_directions(self) -> np.ndarray:
        """Unit slip directions m (n_el, 3) of the committed state (the path measure's): in 2D the
        elemental EDE's; in 3D, where the law is isotropic in the crack's plane, along each cut cell's
        mean plastic slip, or its mean shear traction before it slides, with the dilatancy psi."""
        if self.dim == 2:
            return super().slip_directions()
        out = np.zeros((self.cells.shape[0], 3))
        if not self.cc_cell.size:
            return out
        along = self.cc_wk / self.cc_wk.sum(axis=1, keepdims=True)
        slip = np.einsum("ck,cki->ci", along, self.cc_cp[..., EP.C3_JP:EP.C3_JP + 2])
        shear = np.einsum("ck,cki->ci", along, self.cc_cp[..., EP.C3_T:EP.C3_T + 2])
        tangential = np.where((np.abs(slip).sum(axis=1) > 0.0)[:, None], slip, shear)
        size = np.linalg.norm(tangential, axis=1)
        tangential = np.where(size[:, None] > 0.0, tangential / np.where(size > 0.0, size, 1.0)[:, None],
                              np.array([1.0, 0.0]))
        psi = np.array([strengths(g, 1.0, self.surface_params)[2] for g in self.e_state[self.cc_cell, K.E_GAMMA]])
        local = np.column_stack([np.cos(psi)[:, None] * tangential, np.sin(psi)])  # in (t1, t2, n)
        out[self.cc_cell] = np.einsum("ci,cij->cj", local, self.cc_frame)
        return out

    def _open(self, e: int, ratio: float, loc, tip=None, normal: np.ndarray | None = None) -> None:
        """As the elemental EDE; in 3D a crack continued from a tip stays in the neighbour's plane
        (through the tip point, with its normal), so the two cells share its trace on their face."""
        if self.dim == 3 and not self.plane_strain and tip is not None:
            normal = np.asarray(tip[1], dtype=float)
        super()._open(e, ratio, loc, tip, normal)

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
        its two sides' quadrature and the crack's points (module doc)."""
        c_p = super().localize_cell(e, normal, c_p, point)
        s = self.e_state[e]
        dim = self.dim
        n, t = s[K.E_N:K.E_N + dim], s[K.E_T:K.E_T + dim]
        xe = self.x[e]
        if dim == 2:
            cc = cut_cell(self.ref, xe, self.anchor[e, :2], n)
        else:
            cc = cut_cell_3d(self.ref, xe, self.anchor[e], n)
        m, points = cc.weights.size, cc.crack_weights.size
        if m > self.cc_w.shape[1] or points > self.cc_wk.shape[1]:
            raise RuntimeError(f"cell {e}: {m} side and {points} crack points, more than the "
                               f"{self.cc_w.shape[1]} and {self.cc_wk.shape[1]} of a {self.ref.name} cell")
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
        self.cc_nside[slot, :m] = self.ref.shape(cc.xi)
        self.cc_hnode[slot] = self.active[e]
        # each side point takes the committed state of its nearest Gauss point, with the plastic strain
        # that gives that point's stress at the side point's strain (the cut changes no stress); every
        # crack point the traction of the cell's mean stress (eq. 28, as the elemental EDE: q, P, c_p)
        gauss = quadrature_points(self.nodes, self.cells[e:e + 1], self.ref)[0]  # (n_qp, dim)
        nearest = np.argmin(np.linalg.norm(cc.x[:, None, :] - gauss[None, :, :], axis=2), axis=1)
        sigma = self.sigma[e, nearest]
        if self._sigma0 is not None:  # with the in-situ stress's variation from the Gauss point to the side point
            sigma = sigma + self._sigma0(cc.x) - self._sigma0(gauss[nearest])
        self.cc_state[slot, :m] = self.state[e, nearest]
        self.cc_state[slot, :m, S_MODE] = 0.0
        strain = self._strains_at(e, self.cc_grads[slot, :m])
        self.cc_state[slot, :m, S_EPS_P:S_EPS_P + 6] = strain - sigma @ self._compliance
        self.cc_sigma[slot, :m] = sigma
        self.cut_energy += (strain_energy(sigma, self.cc_w[slot, :m], self.E, self.nu)
                            - strain_energy(self.sigma[e], self.wdet[e], self.E, self.nu))
        self.cc_shape[slot, :points] = self.ref.shape(cc.crack_xi)
        self.cc_wk[slot, :points] = cc.crack_weights
        if dim == 2:
            self.cc_frame[slot, 0], self.cc_frame[slot, 1] = t, n
        else:  # t1 along the shear traction at the cut (q >= 0 along it), t2 = n x t1
            self.cc_frame[slot] = [t, np.cross(n, t), n]
        start = np.zeros(dim)
        start[0], start[-1] = s[K.E_Q], s[K.E_P]  # (q, 0, P) in the crack's frame
        starts = np.broadcast_to(start, (points, dim))
        if self._sigma0 is not None:  # each point with the in-situ stress's variation from the cell's mean
            w = self.wdet[e] / self.wdet[e].sum()
            change = self._sigma0(cc.crack_x) - w @ self._sigma0(gauss)  # (points, 6) Voigt [Pa]
            starts = starts + np.einsum("ij,pjk,k->pi", self.cc_frame[slot], _tensors(change, dim), n)
        for k in range(points):
            self.cc_cp[slot, k] = (EP.initial_state(starts[k, 0], starts[k, 1], c_p) if dim == 2
                                   else EP.initial_state_3d(starts[k], c_p))
        if dim == 2:  # the slip sense is the cell's
            self.cc_cp[slot, :points, EP.CP_SIGN] = 1.0 if s[K.E_Q] >= 0.0 else -1.0
        self._record_sides(slot, e, cc)
        self.cc_trial[slot], self.cc_trial_sigma[slot] = self.cc_state[slot], self.cc_sigma[slot]
        self.cc_cp_trial[slot] = self.cc_cp[slot]
        self.cut_slot[e] = slot
        if self.registry is not None:
            self.registry.register_cut(self, e)  # its order and crack (on several ranks, once announced)
        return c_p

    def set_initial_stress(self, stress: StressField) -> None:
        """As every Drucker-Prager group; the field is kept for the cells cut later (their side and
        crack points take its value where they lie, not their Gauss point's)."""
        super().set_initial_stress(stress)
        self._sigma0 = stress

    def enriched_body_forces(self, body: dict[str, np.ndarray], n_dofs: int) -> np.ndarray | None:
        """The q part (n_dofs,) of the nodal forces of body forces [N/m^3] per region (gravity: density
        times g): node a's q takes the integral of e_a (H - H_a) N_a b over its cut cells' sides."""
        b = body.get(self.region)
        if b is None or not np.any(b) or not self.cc_cell.size:
            return None
        assert self.registry is not None
        enr = self.enrichment()[self.cc_cell]
        factor = enr[:, None, :] * (self.cc_side[:, :, None] - self.cc_hnode[:, None, :])  # (c, m, k)
        share = np.einsum("cp,cpk,cpk->ck", self.cc_w, self.cc_nside, factor)
        q = self.registry.dofs(self.cells[self.cc_cell])
        out = np.zeros(n_dofs)
        np.add.at(out, q.ravel(), (share[:, :, None] * np.asarray(b, dtype=float)[None, None, :]).ravel())
        return out

    def cut_announced(self, gcell: int) -> None:
        """Every rank enters the cut of mesh cell gcell in the enrichment registry (several ranks)."""
        if self.registry is not None:
            self.registry.announce(gcell)

    def _record_sides(self, slot: int, e: int, cc) -> None:
        """The cell's sides the crack crosses (mesh nodes) and its trace on each: 2D its end point on
        the edge, 3D its segment on the face."""
        conn = self.cells[e]
        if self.dim == 2:
            k = conn.shape[0]
            for j, (a, x) in enumerate(zip(cc.crack_edges, cc.crack_x[[0, -1]])):
                self.cc_sides[slot, j] = [conn[a], conn[(a + 1) % k]]
                self.cc_traces[slot, j, 0] = x
            return
        d = (self.x[e] - self.anchor[e]) @ self.e_state[e, K.E_N:K.E_N + 3]
        for j, f in enumerate(cc.crack_edges):
            face = FACES[self.ref.name][f]
            self.cc_sides[slot, j, :len(face)] = conn[list(face)]
            ends = []
            for a, b in zip(face, face[1:] + face[:1]):
                if min(d[a], d[b]) < 0.0 < max(d[a], d[b]):
                    ends.append(self.x[e, a] + d[a] / (d[a] - d[b]) * (self.x[e, b] - self.x[e, a]))
            self.cc_traces[slot, j] = ends[:2]

    def _strains_at(self, e: int, grads: np.ndarray) -> np.ndarray:
        """Voigt strains (m, 6) of cell e's displacements of the last evaluation (the committed ones at a
        commit) at points with shape gradients grads (m, k, dim) (engineering shear; plane strain in 2D)."""
        d = self._last_d[e].reshape(-1, self.dim)
        gu = np.einsum("pai,aj->pij", grads, d)  # d u_j / d x_i
        out = np.zeros((grads.shape[0], 6))
        out[:, 0], out[:, 1], out[:, 3] = gu[:, 0, 0], gu[:, 1, 1], gu[:, 0, 1] + gu[:, 1, 0]
        if self.dim == 3:
            out[:, 2], out[:, 4], out[:, 5] = gu[:, 2, 2], gu[:, 1, 2] + gu[:, 2, 1], gu[:, 0, 2] + gu[:, 2, 0]
        return out

    def crossed_sides(self, e: int) -> list[tuple[tuple[int, ...], np.ndarray]]:
        """Where cut cell e's crack crosses its sides: (the side's mesh nodes, the crack's trace on it)."""
        slot = self.cut_slot[e]
        out = []
        for nodes, trace in zip(self.cc_sides[slot], self.cc_traces[slot]):
            if nodes[0] >= 0:
                out.append((tuple(int(v) for v in nodes if v >= 0), trace))
        return out

    def split_side(self, e: int, nodes: tuple[int, ...]) -> dict[int, np.ndarray]:
        """For each node a of a side of cut cell e that the crack crosses: (H_other - H_a) times the
        integrals of N_a N_b over the part of the side across the crack from a, b over the side's
        nodes [m in 2D, m^2 in 3D] (the share on a's enrichment of a traction interpolated from the
        side's nodes: exact for a linear one)."""
        h = {int(a): float(v) for a, v in zip(self.cells[e], self.active[e])}
        local = [int(np.flatnonzero(self.cells[e] == v)[0]) for v in nodes]
        xs = self.x[e, local]
        n = self.e_state[e, K.E_N:K.E_N + self.dim]
        dist = (xs - self.anchor[e, :self.dim]) @ n
        out = {}
        for a, node in zip(local, nodes):
            other = 1.0 - h[node]
            part = clip_by(xs, dist, 1.0 if other == 1.0 else -1.0)  # the side's part across from a
            if part.shape[0] < 2:
                continue
            if self.dim == 2:  # two Gauss points: N_a N_b is quadratic along the edge
                half = 0.5 * (part[1] - part[0])
                mid = 0.5 * (part[0] + part[1])
                g = half / math.sqrt(3.0)
                pts, w = np.array([mid - g, mid + g]), np.full(2, np.linalg.norm(half))
            else:  # six points of degree 4 on each triangle of the part (N_a N_b: bilinear squared)
                rule, rule_w = TRIANGLE_RULE_6
                pts_list, w_list = [], []
                for j in range(1, part.shape[0] - 1):
                    tri = part[[0, j, j + 1]]
                    area = 0.5 * np.linalg.norm(np.cross(tri[1] - tri[0], tri[2] - tri[0]))
                    pts_list.append(rule @ tri)
                    w_list.append(rule_w * area)
                pts, w = np.vstack(pts_list), np.concatenate(w_list)
            shape = self.ref.shape(inverse_map(self.ref, self.x[e], pts))[:, local]  # (points, side nodes)
            out[node] = (other - h[node]) * ((w * shape[:, local.index(a)]) @ shape)
        return out

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

    def _vec(self, arr: np.ndarray, name: str) -> np.ndarray:
        """A crack points' vector slot (..., dim) of a state array (..., N)."""
        k = self._slot[name]
        return arr[..., k:k + self.dim]

    def commit(self) -> None:
        DruckerPragerSolid.commit(self)  # the uncut cells' Gauss points (a cut cell's are held)
        if self.cc_w.shape[0]:
            d_eps = self.cc_trial[..., S_EPS_P:S_EPS_P + 6] - self.cc_state[..., S_EPS_P:S_EPS_P + 6]
            self.dissipated += float(0.5 * np.einsum("cpi,cpi,cp->", self.cc_sigma + self.cc_trial_sigma, d_eps,
                                                     self.cc_w))
            d_jp = self._vec(self.cc_cp_trial, "JP") - self._vec(self.cc_cp, "JP")
            t_mean = 0.5 * (self._vec(self.cc_cp, "T") + self._vec(self.cc_cp_trial, "T"))
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
        over their crack points and side points (in 3D the shear traction and jump along t1)."""
        cells = self.cc_cell
        cp = self.cc_cp
        st = self.e_state
        frame = self.cc_frame
        dim = self.dim
        along = self.cc_wk / self.cc_wk.sum(axis=1, keepdims=True)  # means along each cell's crack

        def mean(slot: int) -> np.ndarray:
            return np.einsum("ck,ck->c", along, cp[..., slot])

        sl = self._slot
        j_loc = np.column_stack([mean(sl["J"] + i) for i in range(dim)])  # (c, dim) in the frame
        st[cells, K.E_J:K.E_J + dim] = np.einsum("ci,cij->cj", j_loc, frame)
        st[cells, K.E_Q] = mean(sl["T"])
        st[cells, K.E_P] = mean(sl["T"] + dim - 1)
        st[cells, K.E_GAMMA] = mean(sl["GAMMA"])
        st[cells, K.E_ZETA] = mean(sl["ZETA"])
        st[cells, K.E_DZETA] = mean(sl["DZ"])
        st[cells, K.E_MODE] = (cp[..., sl["MODE"]] > 0.0).any(axis=1)  # 1: a point flowed in the step
        # the slip sense: the slide's so far (a crack with no strength left has no shear to tell it)
        slip = mean(sl["JP"])
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
        je = self._vec(cp, "J") - self._vec(cp, "JP")
        t0 = self._vec(cp, "T0")
        k = np.full(self.dim, self.kt)
        k[-1] = self.kn
        crack = np.einsum("cki,cki->ck", t0, je) + 0.5 * np.einsum("i,cki->ck", k, je ** 2)
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


def _tensors(voigt: np.ndarray, dim: int) -> np.ndarray:
    """Stress tensors (p, dim, dim) of Voigt rows (p, 6): xx, yy, zz, xy, yz, xz."""
    index = np.array([[0, 3, 5], [3, 1, 4], [5, 4, 2]])[:dim, :dim]
    return voigt[:, index]
