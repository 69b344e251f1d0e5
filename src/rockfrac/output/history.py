"""The quantities of history.csv: one row per converged step.

- ``step, stage, control, load_factor, time`` (time = stage index + load factor), Newton iterations
  and cutbacks;
- per named node group G and component c: the mean displacement ``u_G_c`` [m] and the reaction
  ``R_G_c`` = sum over the group of f_int - f_ext [N/m per unit thickness in 2D; N in 3D; the
  plane-strain hex8 per unit thickness]: the force the supports (or the loads) apply to the body;
- the monitors ([[monitors]]): ``<name>_x, <name>_y`` of a point, ``<name>`` of an opening;
- energies [J, per unit thickness as the forces]: ``W_external`` (work of all forces on the body,
  trapezoidal over the steps), ``E_elastic`` (stored in the bulk and in the EP penalties),
  ``D_dissipated`` (bulk plasticity, cohesive plastic jumps, embedded jumps, each integrated at
  its own points), and ``energy_error`` = W - (E - E(t=0)) - D, zero up to the time integration;
  ``D_surface_law``: the dissipation the traction laws count on the crack surfaces (cohesive: each
  law's own work variables, independent of the time integration above; embedded cracks: |S| <T> . dJ
  over the steps, which the element's own dissipation should equal and, with its constant jump and
  averaged traction, does not: see README); ``D_viscous`` (only with a viscous regularisation,
  [cohesive] viscosity): the part of D_dissipated the regularisation added, not the law's;
  ``D_bending`` (only with ``[cohesive] points = "edges"`` or ``"faces"``): the part of D_dissipated
  the facet points' plastic bending took (its moment capped by the tension cap), not the law's;
- the crack quantities of the discontinuities (mean plastic jump and strengths, counts);
- ``n_fragments`` (a mesh with cohesive surfaces): the pieces the surfaces that lost their tensile
  strength have cut the body into (:mod:`rockfrac.output.fragments`; 1 while it is whole), and
  ``separated``: the size of those surfaces [m^2 in 3D; m in 2D and per unit thickness for the
  plane-strain hex8, as the forces];
- for the paper's [loading] form, ``u_axial`` (top shortening) and ``F_axial`` (top reaction,
  positive in compression).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import scipy.sparse as sp

from rockfrac.elements.base import ElementGroup
from rockfrac.elements.cse_groups import CohesiveEP, CohesiveRP
from rockfrac.elements.solid import SolidGroup
from rockfrac.laws.traction_law import SEPARATED
from rockfrac.mesh.mesh import Mesh
from rockfrac.model import Model
from rockfrac.output.fragments import Fragments, Pieces
from rockfrac.solve.stepping import StepInfo

BASE = ["step", "stage", "control", "load_factor"]
ALIASES = ["u_axial", "F_axial"]
COUNTS = ["newton_iterations", "cutbacks"]
CRACK = ["jump_p_norm", "chi", "c", "tan_phi", "tan_psi", "n_plastic", "det_ratio", "n_localized", "bulk_plastic",
         "n_fragments", "separated"]
ENERGY = ["W_external", "E_elastic", "D_dissipated", "energy_error", "D_surface_law"]
AXES = "xyz"


@dataclass
class Monitor:
    """A followed quantity: a node's displacement (direction None: columns <name>_x, ...) or the
    opening of the mean of nodes[1] against nodes[0] along a unit direction (column <name>)."""

    name: str
    columns: list[str]
    nodes: tuple[np.ndarray, ...]
    direction: np.ndarray | None
    note: str  # what run.log says about it (which nodes)
    counts: tuple[int, ...] | None = None  # the nodes of each side in the whole mesh (None: as many as nodes)

    def count(self, k: int) -> int:
        """How many nodes side k has in the whole mesh (its mean's denominator)."""
        return self.counts[k] if self.counts is not None else int(np.asarray(self.nodes[k]).shape[0])

    def on_piece(self, ids: np.ndarray) -> Monitor:
        """The monitor on a rank's piece of the mesh (``ids``: the whole index of each of its nodes,
        ascending): the nodes it has, in its numbering; the whole mesh's counts kept."""
        def local(nodes: np.ndarray) -> np.ndarray:
            at = np.minimum(np.searchsorted(ids, nodes), ids.shape[0] - 1)
            return at[ids[at] == nodes]

        counts = tuple(self.count(k) for k in range(len(self.nodes)))
        return replace(self, nodes=tuple(local(np.asarray(n)) for n in self.nodes), counts=counts)


def axial_columns(u: np.ndarray, f_int: np.ndarray, axial_dofs: np.ndarray, thickness: float) -> dict:
    """u_axial, F_axial of the [loading] form (the paper's Fig. 5 axes)."""
    reaction = f_int[axial_dofs].sum() / thickness  # per unit thickness; no external force on top
    return {"u_axial": -float(u[axial_dofs].mean()), "F_axial": -float(reaction)}


MEANS = ("jump_p_norm", "chi", "c", "tan_phi", "tan_psi")  # point records averaged into the history


def crack_columns(groups: list[ElementGroup], rec: dict | None, means: tuple[str, ...] = MEANS,
                  model: Model | None = None) -> dict:
    """Means of the discontinuities' point records, counts, the embedded event and bulk plasticity
    (rec: every point's; the groups' own quantities summed over the ranks of a distributed ``model``)."""
    row: dict = {}
    if rec is not None and rec["state"].size:
        for k in means:
            if k in rec:
                row[k] = float(np.mean(rec[k]))
        row["n_plastic"] = int(np.sum(rec["state"] == "plastic"))
    elif rec is not None:
        row["n_plastic"] = 0
    if model is None or not model.distributed:
        events = [e for g in groups if (e := g.committed_event()) is not None]
        if events:
            row["det_ratio"] = min(events)
            row["n_localized"] = int(sum(g.localized_count() for g in groups))
        solids = [g for g in groups if isinstance(g, SolidGroup)]
        fractions = [(f, g.wdet.size) for g in solids if g.wdet.size and (f := g.plastic_fraction()) is not None]
        if fractions:
            row["bulk_plastic"] = sum(f * n for f, n in fractions) / sum(n for _, n in fractions)
        return row
    events = [e for g in groups if (e := g.committed_event()) is not None]
    if model.reduce_any(bool(events)):
        row["det_ratio"] = model.reduce_min(min(events, default=np.inf))
        row["n_localized"] = int(model.reduce_sum(sum(g.localized_count() for g in groups)))
    solids = [g for g in groups if isinstance(g, SolidGroup)]
    fractions = [(f, g.wdet.size) for g in solids if g.wdet.size and (f := g.plastic_fraction()) is not None]
    if model.reduce_any(bool(fractions)):
        row["bulk_plastic"] = (model.reduce_sum(float(sum(f * n for f, n in fractions)))
                               / model.reduce_sum(float(sum(n for _, n in fractions))))
    return row


def step_columns(info: StepInfo) -> dict:
    return {"step": info.step, "stage": info.stage, "load_factor": info.load_factor,
            "newton_iterations": info.newton.iterations, "cutbacks": info.cutbacks, "control": info.controlled_by}


class History:
    """The columns of history.csv for a built case and the row of each converged step.

    The work W_external is accumulated over the steps, so the object carries (W, u, f) of the last
    step; :meth:`state` and :meth:`restore` put them in and out of a checkpoint.
    """

    def __init__(self, mesh: Mesh, model: Model, *, thickness: float, u0: np.ndarray, f0: np.ndarray,
                 monitors: list[Monitor], axial_dofs: np.ndarray | None = None, axial_count: int | None = None,
                 means: tuple[str, ...] = (), separated_fraction: float = SEPARATED, whole: Mesh | None = None):
        """means: point records averaged into columns besides MEANS (a traction law's own);
        separated_fraction: the tensile strength left, relative, below which a cohesive point lets go;
        axial_count: the axial group's nodes in the whole mesh (None: those of ``axial_dofs``). On an
        MPI rank ``mesh`` is the rank's piece of the mesh, and ``whole`` the whole mesh on the rank
        that counts the fragments (rank 0; None elsewhere)."""
        self.axial_count = axial_count
        self.means = MEANS + tuple(m for m in means if m not in MEANS)
        self.mesh, self.model, self.thickness, self.axial_dofs = mesh, model, thickness, axial_dofs
        self.dim = mesh.dim
        self.n_u = model.n_u  # the displacement dofs of the model's vectors (an MPI rank's local ones)
        # the node groups (of the whole mesh: a rank's piece holds some of their nodes) and their sizes
        self.sizes = (mesh.place.node_set_sizes if mesh.place is not None
                      else {n: len(v) for n, v in mesh.node_sets.items()})
        self.groups = {name: np.asarray(ids) for name, ids in mesh.node_sets.items() if self.sizes[name]}
        self.monitors = monitors
        group_cols = [f"{q}_{g}_{a}" for g in self.groups for q in ("u", "R") for a in AXES[: self.dim]]
        extra = [m for m in self.means if m not in CRACK]
        self.reserved = BASE + ALIASES + COUNTS + CRACK + extra + ENERGY + ["D_viscous", "D_bending", "time"] + group_cols
        self.viscous = model.reduce_any(any(g.viscous_energy() is not None for g in model.groups))
        self.bending = model.reduce_any(any(g.bending_energy() is not None for g in model.groups))
        self.surfaces = [g for g in model.groups if isinstance(g, (CohesiveEP, CohesiveRP))]
        n_if = mesh.place.n_interfaces if mesh.place is not None else mesh.interfaces.shape[0]
        self.counts_fragments = n_if > 0
        self.fragments = Fragments(whole if whole is not None else mesh) if n_if and (
            mesh.place is None or whole is not None) else None
        self.pieces: Pieces | None = None  # the fragments at the last row
        self.separated_fraction = separated_fraction
        # a model whose cracks cut cells as they grow (nodal embedded cracks): each cut changes the
        # discrete system at the committed displacement, and the internal forces of the new one,
        # not those the step converged to, start the next step's work
        self.cuts = model.enrichment_version() is not None
        self.reserved.append("E_released")
        self.columns = (BASE + (ALIASES if axial_dofs is not None else []) + COUNTS + CRACK + extra + ["time"]
                        + group_cols + [c for m in monitors for c in m.columns] + ENERGY
                        + (["D_viscous"] if self.viscous else []) + (["D_bending"] if self.bending else [])
                        + (["E_released"] if self.cuts else []))
        self.n_w = model.n_dofs if self.cuts else self.n_u  # the dofs whose forces work (the enrichments' too)
        self._linear = self._functionals()
        self.e0 = self.elastic_energy(u0)
        self.work = 0.0
        self.released = 0.0
        self.u_prev = u0[: self.n_w].copy()
        self.f_prev = self._initial_f_int(u0, f0)
        self.f_post: np.ndarray | None = None  # internal forces of the system after the last commit's cuts

    def _initial_f_int(self, u0: np.ndarray, f0: np.ndarray) -> np.ndarray:
        """f_int at t = 0 (zero for a stress-free start; else the state's internal forces)."""
        if not self.model.reduce_any(bool(np.any(f0) or np.any(u0))):  # on any rank's dofs
            return np.zeros(self.n_w)
        self.model.begin_step()
        return self._owned(self.model.assemble(u0, u0, f0).f_int)

    def after_cuts(self, u: np.ndarray, f_ext: np.ndarray) -> None:  # f_ext: shapes only (f_int is the use)
        """The internal forces of the committed system at u (cells cut at the commit included), which
        start the next step's work (models whose cracks cut cells; an assembly per step)."""
        if self.cuts:
            self.model.begin_step()
            self.f_post = self._owned(self.model.assemble(u, u, f_ext).f_int)

    def _owned(self, f: np.ndarray) -> np.ndarray:
        """The forces' first n_w entries, zero where another MPI rank owns the dof: a dot product with
        them, summed over the ranks, counts every dof once (serial: a copy)."""
        return self.model.owned(f)[: self.n_w].copy()

    def _functionals(self) -> tuple[list[str], sp.csr_matrix, list[str], sp.csr_matrix, list[str], sp.csr_matrix]:
        """The row's quantities linear in the displacements (group means, monitors, u_axial), in the
        internal forces (F_axial) and in the reactions f_int - f_ext (group sums): their names and
        matrices over the displacement dofs, each rank's restricted to the dofs it owns, so that the
        values are the sums of the ranks' products (one reduction per row)."""
        d, on_u, on_f, on_r = self.dim, [], [], []
        if self.axial_dofs is not None:
            n = self.axial_count if self.axial_count is not None else len(self.axial_dofs)  # the whole group's
            on_u.append(("u_axial", self.axial_dofs, np.full(len(self.axial_dofs), -1.0 / n)))
            on_f.append(("F_axial", self.axial_dofs, np.full(len(self.axial_dofs), -1.0 / self.thickness)))
        for g, ids in self.groups.items():
            for a in range(d):
                on_u.append((f"u_{g}_{AXES[a]}", d * ids + a, np.full(ids.size, 1.0 / self.sizes[g])))
                on_r.append((f"R_{g}_{AXES[a]}", d * ids + a, np.full(ids.size, 1.0 / self.thickness)))
        for m in self.monitors:
            if m.direction is None:
                on_u += [(col, d * np.asarray(m.nodes[0][:1]) + a, np.ones(len(m.nodes[0][:1])))
                         for a, col in enumerate(m.columns)]
                continue
            a_, b_ = np.asarray(m.nodes[0]), np.asarray(m.nodes[1])
            dofs = np.concatenate([d * b_[:, None] + np.arange(d), d * a_[:, None] + np.arange(d)]).ravel()
            weights = np.concatenate([np.tile(m.direction / m.count(1), (b_.size, 1)),
                                      np.tile(-m.direction / m.count(0), (a_.size, 1))]).ravel()
            on_u.append((m.name, dofs, weights))
        own = self.model.owned(np.ones(self.model.n_dofs))[: self.n_u]

        def matrix(rows: list) -> sp.csr_matrix:
            i = np.concatenate([np.full(len(dofs), k) for k, (_, dofs, _) in enumerate(rows)] + [np.zeros(0, int)])
            j = np.concatenate([dofs for _, dofs, _ in rows] + [np.zeros(0, int)])
            v = np.concatenate([w for _, _, w in rows] + [np.zeros(0)])
            j, held = self.model.local_dofs(j)  # global dofs: an MPI rank's own count, the others' are 0 here
            return sp.csr_matrix((v[held] * own[j], (i[held], j)), shape=(len(rows), self.n_u))

        return ([n for n, _, _ in on_u], matrix(on_u), [n for n, _, _ in on_f], matrix(on_f),
                [n for n, _, _ in on_r], matrix(on_r))

    @property
    def notes(self) -> list[str]:
        return [m.note for m in self.monitors]

    def elastic_energy(self, u: np.ndarray) -> float:
        """[J, per unit thickness in 2D] (u: on the rank's local dofs; the groups' sums over the ranks)."""
        return self.model.reduce_sum(sum(g.elastic_energy(u) for g in self.model.groups)) / self.thickness

    def dissipated(self) -> float:
        return self.model.reduce_sum(sum(g.dissipated_energy() for g in self.model.groups)) / self.thickness

    def state(self) -> dict[str, np.ndarray]:
        return {"work": np.array(self.work), "released": np.array(self.released), "u_prev": self.u_prev,
                "f_prev": self.f_prev}

    def restore(self, saved: dict[str, np.ndarray]) -> None:
        self.work = float(saved["work"])
        self.released = float(saved.get("released", 0.0))
        self.u_prev = saved["u_prev"][: self.n_w].copy()
        f = saved["f_prev"]
        self.f_prev = self._owned(f) if f.shape[0] == self.model.n_dofs else f[: self.n_w].copy()

    def row(self, info: StepInfo, rec: dict | None) -> dict:
        """Every column of the step (committed state)."""
        row = step_columns(info)
        row.update(crack_columns(self.model.groups, rec, self.means, self.model))
        if self.counts_fragments:
            mine = [g.separated(self.separated_fraction) for g in self.surfaces]
            none = np.zeros((0, 2), dtype=np.int64)
            pairs = np.concatenate([p for p, _ in mine] + [none])
            held = none  # one process: separated() has the whole of every pair
            if self.mesh.place is not None:  # an MPI rank: the pairs it still holds, in the whole mesh's node numbers
                held = np.concatenate([g.holding(self.separated_fraction) for g in self.surfaces] + [none])
                pairs, held = self.mesh.place.nodes[pairs], self.mesh.place.nodes[held]
            every = self.model.gather_lead(pairs)  # to the rank that counts the pieces
            every_held = self.model.gather_lead(held)
            if self.fragments is not None:
                assert every is not None and every_held is not None
                self.pieces = self.fragments.pieces(np.concatenate(every), np.concatenate(every_held))
            row["n_fragments"] = self.model.share(self.pieces.count if self.pieces is not None else 0)
            row["separated"] = self.model.reduce_sum(sum(a for _, a in mine)) / self.thickness
        row["time"] = info.stage_index + info.load_factor
        f_ext = info.f_ext if info.f_ext is not None else np.zeros_like(info.f_int)
        names_u, on_u, names_f, on_f, names_r, on_r = self._linear
        values = self.model.reduce_sum(np.concatenate([on_u @ info.u[: self.n_u], on_f @ info.f_int[: self.n_u],
                                                       on_r @ (info.f_int - f_ext)[: self.n_u]]))
        row.update({name: float(v) for name, v in zip(names_u + names_f + names_r, values)})
        f_now = self._owned(info.f_int)
        u_now = info.u[: self.n_w]
        du = u_now - self.u_prev
        start, released = self.f_prev, 0.0
        if self.f_post is not None:  # the last commit cut cells: the reactions jumped to the new system's,
            free = self.model.free[self.model.free < self.n_w]  # and its unbalance on the free dofs is
            jump = self.f_post[free] - self.f_prev[free]  # released as the step relaxes it (E_released)
            released = -0.5 * float(jump @ du[free])
            start = self.f_post.copy()
            start[free] = self.f_prev[free]
        step_work = 0.5 * float((start + f_now) @ du)
        step_work, released = self.model.reduce_sum(np.array([step_work, released]))
        self.work += step_work / self.thickness
        self.released += released / self.thickness
        self.u_prev, self.f_prev = u_now.copy(), f_now
        self.after_cuts(info.u, f_ext)
        e_el, dissipated = self.elastic_energy(info.u), self.dissipated()
        released = self.released
        if self.cuts:  # less the stored energy the cut cells' new quadrature gave them at fixed u
            released -= self.model.reduce_sum(sum(g.recut_energy() for g in self.model.groups)) / self.thickness
        row.update(W_external=self.work, E_elastic=e_el, D_dissipated=dissipated,
                   energy_error=self.work - (e_el - self.e0) - dissipated - released,
                   D_surface_law=self.model.reduce_sum(sum(g.surface_energy() for g in self.model.groups))
                   / self.thickness)
        if self.viscous:
            row["D_viscous"] = self.viscous_dissipated()
        if self.bending:
            row["D_bending"] = self.model.reduce_sum(
                sum(e for g in self.model.groups if (e := g.bending_energy()) is not None)) / self.thickness
        if self.cuts:
            row["E_released"] = released
        return row

    def viscous_dissipated(self) -> float:
        """The dissipation the viscous regularisations added (D_viscous) [J, per unit thickness in 2D]."""
        return self.model.reduce_sum(sum(e for g in self.model.groups if (e := g.viscous_energy()) is not None)
                                     ) / self.thickness
