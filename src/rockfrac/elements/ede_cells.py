"""EDE cells' state, checkpoint, element evaluation, path following and output (no localization)."""

from __future__ import annotations

import numpy as np

from rockfrac.elements import ede_kernel as K
from rockfrac.elements.base import Evaluation, Measure
from rockfrac.elements.ede_paths import CrackPaths, Onset
from rockfrac.fem.planes import EDGES, plane_polygons, polygon_areas
from rockfrac.elements.plastic_solid import DruckerPragerSolid
from rockfrac.fem.reference import ReferenceElement
from rockfrac.laws.drucker_prager_params import DruckerPrager
from rockfrac.laws.mohr_coulomb_softening import EmbeddedLaw, strengths


def shear_directions(sigma: np.ndarray, n: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The shear traction of stresses sigma (k, 3, 3) [Pa] on planes of unit normals n (k, 3): its
    direction t (k, 3), magnitude q (k,) [Pa] and where it is defined (q above 1e-12 of the traction)."""
    traction = np.einsum("cij,cj->ci", sigma, n)
    shear = traction - np.einsum("ci,ci->c", traction, n)[:, None] * n
    q = np.linalg.norm(shear, axis=1)
    ok = q > 1e-12 * np.maximum(np.abs(traction).max(axis=1), 1e-300)
    return shear / np.where(ok, q, 1.0)[:, None], q, ok


class EmbeddedCells(DruckerPragerSolid):
    """The cells of :class:`rockfrac.elements.ede.EmbeddedDruckerPrager` apart from their localization."""

    checkpoint_attrs: tuple[str, ...] = ("state", "sigma", "dissipated", "crack_dissipated", "surface_dissipated", "e_state",
                        "gradf", "active", "anchor", "segments", "sections", "last_event", "crack_count",
                        "deferred")

    def checkpoint_state(self) -> dict[str, np.ndarray]:
        """The committed state as named arrays, the onsets (a list of records) packed into arrays."""
        out = super().checkpoint_state()
        o = self.onsets
        out["onset_cell"] = np.array([x.cell for x in o], dtype=np.int64)
        out["onset_scalars"] = np.array([[x.band_angle, x.det_ratio, x.c_p, x.conjugate_band_angle]
                                         for x in o]).reshape(-1, 4)
        out["onset_normal"] = np.array([x.normal for x in o]).reshape(-1, 3)
        out["onset_count"] = np.array([len(x.normals) for x in o], dtype=np.int64)
        out["onset_normals"] = np.concatenate([np.asarray(x.normals).reshape(-1, 3) for x in o] or [np.zeros((0, 3))])
        out["onset_slips"] = np.concatenate([np.asarray(x.slips).reshape(-1, 3) for x in o] or [np.zeros((0, 3))])
        return out

    def restore_checkpoint(self, saved: dict[str, np.ndarray]) -> None:
        super().restore_checkpoint(saved)
        if self._paths is not None:
            self._paths.stale = True  # its table is rebuilt once every group is restored
        names = ("onset_cell", "onset_scalars", "onset_normal", "onset_count", "onset_normals", "onset_slips")
        missing = [n for n in names if n not in saved]
        if missing:
            raise ValueError(f"the checkpoint has no {type(self).__name__}.{missing[0]}: a different model")
        cell, sc, normal, count = (saved[n] for n in names[:4])
        ends = np.cumsum(count)
        if not (cell.shape[0] == sc.shape[0] == normal.shape[0] == count.shape[0]) or \
                (ends[-1] if ends.size else 0) != saved["onset_normals"].shape[0]:
            raise ValueError("the checkpoint's onset records do not fit together (corrupted)")
        starts = ends - count
        self.onsets[:] = [Onset(int(cell[i]), normal[i].copy(), float(sc[i, 0]), float(sc[i, 1]), float(sc[i, 2]),
                             float(sc[i, 3]), saved["onset_normals"][a:b].copy(), saved["onset_slips"][a:b].copy())
                       for i, (a, b) in enumerate(zip(starts, ends))]

    kind = "embedded"

    def __init__(self, nodes: np.ndarray, cells: np.ndarray, ref: ReferenceElement, law: DruckerPrager,
                 surface: EmbeddedLaw, band: str = "positive", plane_strain: bool = True, tracking: str = "none",
                 max_cracks: int = 1, *, region: str = "bulk", cell_ids: np.ndarray | None = None,
                 tracking_length: float | None = None):
        super().__init__(nodes, cells, ref, law, region=region, cell_ids=cell_ids)
        self._paths: CrackPaths | None = None
        self.serial_index = np.arange(cells.shape[0])  # each cell's place in its group's serial order (MPI)
        self.crack_dissipated = 0.0  # the embedded jumps' share of ``dissipated`` [J]
        self.surface_dissipated = 0.0  # sum of |S| <T> . dJ: the traction law's work on the surfaces (2D) [J]
        if band not in ("positive", "negative"):
            raise ValueError(f"band must be 'positive' or 'negative', got {band!r}")
        if tracking not in ("none", "local", "nonlocal"):
            raise ValueError(f"tracking must be 'none', 'local' or 'nonlocal', got {tracking!r}")
        if (tracking == "nonlocal") != (tracking_length is not None):
            raise ValueError("tracking_length [m] is needed by, and only by, tracking = 'nonlocal'")
        self.tracking = tracking
        self.tracking_length = tracking_length  # "nonlocal": the Gaussian length of the tip's stress average [m]
        self.max_cracks = max_cracks  # tracking "local"/"nonlocal": most cracks started (the others are continued)
        self.surface = surface
        self.band = band
        self.plane_strain = plane_strain
        self.x = nodes[cells]  # (n_el, n_nodes, dim)
        self.ce = law.elastic_matrix()
        n_el, n_qp = self.wdet.shape
        self.e_state = np.zeros((n_el, K.N_E))
        self.e_trial = np.zeros_like(self.e_state)
        self.gradf = np.zeros((n_el, n_qp, 3))
        self.active = np.zeros(cells.shape, dtype=bool)  # nodes on the + side of each cell's surface
        self.anchor = np.zeros((n_el, 3))  # a point of each cut cell's surface [m]
        self.segments = np.full((n_el, 2, 2), np.nan)  # 2D: the surface clipped to its cell [m]
        # hexahedra of a plane-strain slab cut by a surface normal to z: its trace on the cell's z face
        # (nodes 0-3) [m], for the crack map and the ParaView lines (NaN otherwise)
        self.sections = np.full((n_el, 2, 2), np.nan)
        self.nodes = nodes
        if tracking != "none" and self.dim != 2 and plane_strain:
            raise ValueError(f"tracking = {tracking!r} follows crack paths in 2D meshes and in hexahedra of a "
                             "general 3D body, not in a plane-strain slab of hexahedra")
        self.onsets: list[Onset] = []
        nd = self.dofs.shape[1]
        self._dz = np.zeros(n_el)  # jump increments of the current iterate
        self._d_prev = np.zeros((n_el, nd))  # element dofs, r, dr/dd, dr/d dzeta of the last evaluation
        self._r_prev = np.zeros(n_el)
        self._h_prev = np.zeros((n_el, nd))
        self._k_prev = np.zeros(n_el)
        self.local_residual = 0.0  # max |r| / c_p of the last evaluation
        self._flips = np.zeros(n_el, dtype=np.int64)  # slide <-> stick switches in the current step
        self._stuck = np.zeros(n_el, dtype=bool)
        self._released = np.zeros(n_el, dtype=bool)
        self.last_event = 1.0  # min det ratio of the committed state over cells that may localize
        # cut at the last commit, or waiting for the stress after its cuts: the next step is a hold
        self.deferred = np.zeros(cells.shape[0], dtype=bool)

    # -- state -----------------------------------------------------------------------------
    def begin_step(self) -> None:
        super().begin_step()
        if self.dim == 3 and not self.plane_strain:
            self.align_slip()
        self.e_trial[:] = self.e_state
        self._dz[:] = 0.0
        self._k_prev[:] = 0.0
        self._flips[:] = 0
        self._stuck[:] = False
        self._released[:] = False

    def _surface_work(self) -> float:
        """The traction law's work over the step on the cut cells' surfaces (2D: length |S| of each
        segment; general 3D: the area of each polygon; 0 for a plane-strain hexahedron): |S| <T> . dJ with T = q t + P n the
        averaged traction (trapezoidal in time) [J]. In an exact formulation it equals
        :meth:`_crack_work`; this element's constant jump and volume-averaged traction make them differ."""
        if self.dim != 2 and self.plane_strain:
            return 0.0
        old, new = self.e_state, self.e_trial
        d_j = new[:, K.E_J:K.E_J + 3] - old[:, K.E_J:K.E_J + 3]
        cut = np.flatnonzero(np.any(d_j != 0.0, axis=1))
        if not cut.size:
            return 0.0
        if self.dim == 2:
            length = np.linalg.norm(self.segments[cut, 1] - self.segments[cut, 0], axis=1)
        else:  # a general 3D body: the areas of the surfaces' polygons
            length = polygon_areas(self.surface_polygons(cut)[0])

        def traction(st):
            return st[cut, K.E_Q, None] * st[cut, K.E_T:K.E_T + 3] + st[cut, K.E_P, None] * st[cut, K.E_N:K.E_N + 3]

        return float(np.sum(length * np.einsum("ci,ci->c", 0.5 * (traction(old) + traction(new)), d_j[cut])))

    def surface_energy(self) -> float:
        return self.surface_dissipated

    def _crack_work(self) -> float:
        """Work of the stresses on the jump increment of the step, sum_q w <sigma> : sym(dJ x grad f_S)
        (trapezoidal in time) [J]: the regular strain is B d - eps^p - sym(J x grad f_S), so this is
        what the bulk gives up to the discontinuity."""
        d_j = self.e_trial[:, K.E_J:K.E_J + 3] - self.e_state[:, K.E_J:K.E_J + 3]
        cut = np.flatnonzero(np.any(d_j != 0.0, axis=1))
        if not cut.size:
            return 0.0
        j, g = d_j[cut][:, None, :], self.gradf[cut]
        e6 = np.concatenate([j * g, j[..., [0]] * g[..., [1]] + j[..., [1]] * g[..., [0]],
                             j[..., [1]] * g[..., [2]] + j[..., [2]] * g[..., [1]],
                             j[..., [0]] * g[..., [2]] + j[..., [2]] * g[..., [0]]], axis=2)
        mean = 0.5 * (self.sigma[cut] + self.trial_sigma[cut])
        return float(np.einsum("eqi,eqi,eq->", mean, e6, self.wdet[cut]))

    def evaluate(self, u: np.ndarray, u_n: np.ndarray) -> Evaluation:
        """Cells at the global iterate u; the jumps follow d dzeta = -(r + h . dd) / k (condensation)."""
        n_el, nd = self.dofs.shape
        d = np.ascontiguousarray(u[self.dofs])
        if np.array_equal(u, u_n):  # first iterate of a step: sliding cells go on sliding
            self._dz[:] = 0.0
            slide = self.e_state[:, K.E_MODE] == 1.0
        else:
            sliding = self._k_prev != 0.0
            dd = d[sliding] - self._d_prev[sliding]
            self._dz[sliding] -= (self._r_prev[sliding] + np.einsum("ei,ei->e", self._h_prev[sliding], dd)) \
                / self._k_prev[sliding]
            slide = sliding & (self._dz > 0.0)
        mode_prev = self.e_trial[:, K.E_MODE].copy()
        fe, ke = self.element_buffers()
        slide &= ~self._stuck
        K.ede_blocks(self.grads, self.wdet, d,
                     self.state, self.p, self.ce, self.e_state, self.gradf, self.surface_params, self._dz,
                     slide, self._stuck, self.trial, self.trial_sigma, self.e_trial, fe, ke, self.status,
                     self._r_prev, self._k_prev, self._h_prev)
        self._d_prev[:] = d
        cp = np.maximum(self.e_state[:, K.E_CP], 1.0)
        # active-set pinning: a cell chattering between sliding and sticking is held rigid for the
        # rest of the step; consistent only if its trial stays inside the surface, else released
        stuck_r = np.where(self._stuck, self._r_prev, 0.0)
        out = self._stuck & (stuck_r > 1e-9 * cp)
        self._stuck[out] = False
        self._released |= out
        sliding_r = np.where(self._stuck, 0.0, self._r_prev)
        self.local_residual = float(max(np.max(np.abs(sliding_r) / cp, initial=0.0),
                                        1.0 if out.any() else 0.0))
        self._r_prev[self._stuck] = 0.0
        loc = self.e_state[:, K.E_LOC] == 1.0
        flipped = loc & (self.e_trial[:, K.E_MODE] != mode_prev)
        self._flips += flipped
        self._stuck |= (self._flips >= 2) & ~self._released & loc
        switched = int(np.sum(flipped))
        bad = np.flatnonzero(self.status < 0)
        if not bad.size:
            return Evaluation(fe, ke, n_switched=switched, local_residual=self.local_residual)
        why = {K.ST_DP_FAIL: "no Drucker-Prager return", K.ST_NOT_UNIQUE: "the jump does not enter eq. (27)"}
        return Evaluation(fe, ke, ok=False, message=f"EDE cells {bad[:5].tolist()}: {why[int(self.status[bad[0]])]}")

    @property
    def surface_params(self) -> np.ndarray:
        return self.surface.as_array(c_p=0.0)  # c_p per cell lives in the state (eq. 28)

    # -- path following ------------------------------------------------------------------
    def any_sliding(self) -> bool:
        """True if a localized cell slid in the committed step."""
        return bool(np.any((self.e_state[:, K.E_LOC] == 1.0) & (self.e_state[:, K.E_MODE] == 1.0)))

    def slip_directions(self) -> np.ndarray:
        """Unit slip directions m = s cos(psi) t + sin(psi) n (n_el, 3) of the committed state."""
        st = self.e_state
        law = self.surface_params
        psi = np.array([strengths(g, 1.0, law)[2] for g in st[:, K.E_GAMMA]])
        return (st[:, K.E_SIGN] * np.cos(psi))[:, None] * st[:, K.E_T:K.E_T + 3] + \
            np.sin(psi)[:, None] * st[:, K.E_N:K.E_N + 3]

    def jump_measure(self):
        """Path-following measure for the next step: the mean over localized cells of the relative
        displacement of their + side nodes against their - side nodes along the committed slip
        direction m_ref [m] (a crack-mouth opening per cell), and its constant gradient.

        Linear in u and independent of the condensed jump: the jump's own linearization,
        -(h . dd)/k, is ill-conditioned wherever dr/d dzeta = k passes through zero during
        softening. It grows with forward slip (the + side carries the slide) and shrinks on the
        reversed branch, which a positive increment therefore never takes.
        """
        m_ref = self.slip_directions()[:, : self.dim]
        loc = np.flatnonzero(self.e_state[:, K.E_LOC] == 1.0)
        coef = np.zeros((self.dofs.shape[0], self.dofs.shape[1]))
        for e in loc:  # once per step, over the localized cells only
            act = self.active[e]
            w = np.where(act, 1.0 / act.sum(), -1.0 / (~act).sum())  # + side mean minus - side mean
            coef[e] = (w[:, None] * m_ref[e][None, :]).ravel() / loc.size

        def measure(u: np.ndarray) -> tuple[float, np.ndarray]:
            grad = np.zeros(u.shape[0])
            if loc.size == 0:
                return 0.0, grad
            np.add.at(grad, self.dofs[loc], coef[loc])
            return float(grad @ u), grad

        return measure

    def path_measure(self, n_dofs: int) -> Measure:
        return self.jump_measure()

    def path_active(self) -> bool:
        return self.any_sliding()

    def path_weight(self) -> int:
        return max(int(self.localized().size), 1)

    def path_count(self) -> int:
        return int(self.localized().size)

    def measure_mass(self) -> float:
        return float(self.localized().size)  # the measure averages over the localized cells

    # -- output ----------------------------------------------------------------------------
    def point_records(self, u: np.ndarray) -> dict[str, np.ndarray]:
        """:meth:`records` with the state named, the mesh's cell numbers and the region as the set."""
        rec = self.records()
        rec["state"] = np.where(rec["mode"] == 1.0, "plastic", "constrained")
        rec["cell"] = self.whole_ids[rec["cell"]]
        rec["set"] = np.full(rec["cell"].shape[0], self.region)
        return rec

    def record_order(self) -> np.ndarray | None:
        return self.serial_index[self.localized()]

    def cell_fields(self, u: np.ndarray) -> dict[str, np.ndarray]:
        out = super().cell_fields(u)
        out["localized"] = self.e_state[:, K.E_LOC].astype(np.int8)
        return out

    def event_log(self) -> list[str]:
        return [f"bifurcation: {o.describe()}" for o in self.onsets]

    def localized_count(self) -> int:
        return int(self.localized().size)

    def localized(self) -> np.ndarray:
        return np.flatnonzero(self.e_state[:, K.E_LOC] == 1.0)

    def averaged_stress(self, cells: np.ndarray) -> np.ndarray:
        """The cells' volume-averaged committed stress tensors (k, 3, 3) [Pa]."""
        w = self.wdet[cells] / self.wdet[cells].sum(axis=1, keepdims=True)
        v = np.einsum("cq,cqi->ci", w, self.sigma[cells])  # Voigt (xx, yy, zz, xy, yz, xz)
        return v[:, [[0, 3, 5], [3, 1, 4], [5, 4, 2]]]

    def align_slip(self) -> None:
        """A general 3D body: each cut cell that has not slid yet takes as its slip direction t the
        direction of the shear traction of its committed averaged stress on its surface (q = |shear|,
        s = 1); from its first slide on, t stays frozen. A crack given in advance is cut before any
        load, so its direction is set by the stress of the steps before it slides."""
        s = self.e_state
        cells = np.flatnonzero((s[:, K.E_LOC] == 1.0) & (s[:, K.E_ZETA] == 0.0))
        if not cells.size:
            return
        t, q, ok = shear_directions(self.averaged_stress(cells), s[cells, K.E_N:K.E_N + 3])
        s[cells[ok], K.E_T:K.E_T + 3] = t[ok]
        s[cells[ok], K.E_SIGN] = 1.0
        s[cells[ok], K.E_Q] = q[ok]

    def surface_polygons(self, cells: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """A general 3D body: where each cut cell's surface cuts it (rockfrac.fem.planes.
        plane_polygons: vertices (k, 6, 3) [m], their edges' end nodes (local to the cell) and places)."""
        cells = np.asarray(cells, dtype=np.int64)
        normal = self.e_state[cells, K.E_N:K.E_N + 3]
        return plane_polygons(self.x[cells], EDGES[self.ref.name], self.anchor[cells], normal)

    def records(self) -> dict[str, np.ndarray]:
        """Committed per-discontinuity quantities (one point per localized cell, local frame (t, n))."""
        cells = self.localized()
        s = self.e_state[cells]
        j = s[:, K.E_J:K.E_J + 3]
        jt = np.einsum("ci,ci->c", j, s[:, K.E_T:K.E_T + 3])
        jn = np.einsum("ci,ci->c", j, s[:, K.E_N:K.E_N + 3])
        law = self.surface_params
        q = np.array([strengths(g, cp, law)[:3] for g, cp in zip(s[:, K.E_GAMMA], s[:, K.E_CP])]).reshape(-1, 3)
        centre = self.x[cells].mean(axis=1) if cells.size else np.zeros((0, self.dim))
        where = {"x": centre[:, 0], "y": centre[:, 1]}
        if self.dim == 3 and not self.plane_strain:  # points.csv's 3D columns: frame (t, n x t, n)
            n = s[:, K.E_N:K.E_N + 3]
            j2 = np.einsum("ci,ci->c", j, np.cross(n, s[:, K.E_T:K.E_T + 3]))
            zero = np.zeros(cells.size)
            where.update({"z": centre[:, 2], "n_x": n[:, 0], "n_y": n[:, 1], "n_z": n[:, 2], "jump_t1": jt,
                          "jump_t2": j2, "T_t1": s[:, K.E_Q], "T_t2": zero, "jump_p_t1": jt, "jump_p_t2": j2})
        return {
            "cell": cells, **where, "jump_t": jt, "jump_n": jn,
            "angle": np.arctan2(s[:, K.E_T + 1], s[:, K.E_T]),
            "T_t": s[:, K.E_Q], "T_n": s[:, K.E_P], "jump_p_t": jt, "jump_p_n": jn,
            "jump_p_norm": np.linalg.norm(j, axis=1), "gamma": s[:, K.E_GAMMA], "zeta": s[:, K.E_ZETA],
            "c": q[:, 0], "tan_phi": q[:, 1], "tan_psi": np.tan(q[:, 2]), "c_p": s[:, K.E_CP],
            "mode": s[:, K.E_MODE],
        }
