"""Drucker-Prager bulk with embedded strong discontinuities (EDE, paper Sect. 3.1, 5; EDE_NOTES).

Every cell is a Drucker-Prager solid until, at the end of a converged step, the acoustic tensor
of eq. (7)-(8) at one of its plastic Gauss points loses ellipticity (min det A / det A^e <= 0).
The cell then localizes for good: a surface through its centroid with that normal (the conjugate
chosen by ``band``), c_p from eq. (28) on the converged stress, the bulk frozen elastic. See
:mod:`rockfrac.elements.ede_kernel` for the element equations.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rockfrac import threads
from rockfrac.elements import ede_kernel as K
from rockfrac.elements.base import Evaluation, Measure
from rockfrac.elements.plastic_solid import DruckerPragerSolid
from rockfrac.fem.reference import ReferenceElement
from rockfrac.laws.bifurcation import localization_at, min_ratios_plane_strain, screen_plane_strain
from rockfrac.laws.drucker_prager_params import MODE_CONE, S_MODE, DruckerPrager
from rockfrac.laws.mohr_coulomb_softening import EmbeddedLaw, strengths
from rockfrac.mesh.geometry import surface_segment


@dataclass(frozen=True)
class Onset:
    """Where and how a cell localized: step count, normal, band angle [rad], det ratio, c_p [Pa]."""

    cell: int
    normal: np.ndarray
    band_angle: float
    det_ratio: float
    c_p: float
    conjugate_band_angle: float
    normals: np.ndarray  # every local minimum of det A(n) / det A^e(n) (the conjugate pair first)
    slips: np.ndarray  # their slip directions (null vectors of A), m . n >= 0

    def describe(self) -> str:
        """One log line: where, which band, the conjugates and their slips."""
        pairs = "; ".join(f"n = ({n[0]:+.5f}, {n[1]:+.5f}, {n[2]:+.5f}) band {np.degrees(b):+.4f} deg, "
                          f"m = ({m[0]:+.5f}, {m[1]:+.5f}, {m[2]:+.5f})"
                          for n, b, m in zip(self.normals, [_band(n) for n in self.normals], self.slips))
        return (f"cell {self.cell} localized: det A / det A^e = {self.det_ratio:.3e}; surface at "
                f"{np.degrees(self.band_angle):+.4f} deg (c_p = {self.c_p:.1f} Pa, eq. 28); minima: {pairs}")


def _band(n: np.ndarray) -> float:
    """Band angle [rad] of the plane with normal n, in (-pi/2, pi/2]."""
    a = math.atan2(n[1], n[0]) % math.pi - 0.5 * math.pi
    return a + math.pi if a <= -0.5 * math.pi else a


class CrackPaths:
    """Crack paths across the EDE groups of a model (2D): cell adjacency over the global cell
    numbering, the cut state of every cell whatever its group, the number of cracks started."""

    def __init__(self, nodes: np.ndarray, groups: list):
        self.nodes = nodes
        self.groups = groups
        self.cracks = 0
        ids = [g.cell_ids for g in groups]
        n_cells = int(max(i.max(initial=-1) for i in ids)) + 1
        self.owner = np.full((n_cells, 2), -1, dtype=np.int64)  # (group, local cell) of each global cell
        cells = []
        for k, (g, i) in enumerate(zip(groups, ids)):
            self.owner[i, 0], self.owner[i, 1] = k, np.arange(i.size)
            cells.append((i, g.cells))
        self.nbr: dict[int, list[tuple[int, int, int]]] = {}
        gids = np.concatenate([i for i, _ in cells])
        conn = np.vstack([c for _, c in cells])
        n = conn.shape[1]
        pairs = np.stack([conn, np.roll(conn, -1, axis=1)], axis=-1).reshape(-1, 2)
        owner = np.repeat(gids, n)
        key = np.sort(pairs, axis=1)
        order = np.lexsort((key[:, 1], key[:, 0]))
        ks = key[order]
        for i in np.flatnonzero(np.all(ks[1:] == ks[:-1], axis=1)):  # once, at set-up
            c1, c2 = int(owner[order[i]]), int(owner[order[i + 1]])
            a, b = int(ks[i, 0]), int(ks[i, 1])
            self.nbr.setdefault(c1, []).append((c2, a, b))
            self.nbr.setdefault(c2, []).append((c1, a, b))

    def _cell(self, gcell: int):
        g, local = self.owner[gcell]
        return (None, -1) if g < 0 else (self.groups[g], int(local))

    def is_cut(self, gcell: int) -> bool:
        g, local = self._cell(gcell)
        return g is not None and g.e_state[local, K.E_LOC] == 1.0

    def cut_neighbours(self, gcell: int) -> list[int]:
        return [c for c, _, _ in self.nbr.get(gcell, []) if self.is_cut(c)]

    def tip(self, gcell: int) -> tuple[np.ndarray, np.ndarray] | None:
        """(point, neighbour normal) where a cut neighbour's surface ends on the edge shared with gcell."""
        for c, a, b in self.nbr.get(gcell, []):
            if not self.is_cut(c):
                continue
            g, local = self._cell(c)
            xa, xb = self.nodes[a, :2], self.nodes[b, :2]
            size = np.linalg.norm(xb - xa)
            for p in g.segments[local]:  # p on edge ab: collinear, between its ends
                cross = abs((xb[0] - xa[0]) * (p[1] - xa[1]) - (xb[1] - xa[1]) * (p[0] - xa[0])) / size
                along = np.dot(p - xa, xb - xa) / size**2
                if cross < 1e-9 * size and -1e-9 <= along <= 1 + 1e-9:
                    return p.copy(), g.e_state[local, K.E_N:K.E_N + 3].copy()
        return None

    def tip_cells(self, group) -> set[int]:
        """Local indices in ``group`` of its uncut cells at a crack tip."""
        k = self.groups.index(group)
        out = set()
        for g in self.groups:
            ids = g.cell_ids
            for e in np.flatnonzero(g.e_state[:, K.E_LOC] == 1.0):
                for c, _, _ in self.nbr.get(int(ids[e]), []):
                    gk, local = self.owner[c]
                    if gk == k and not self.is_cut(c) and self.tip(c) is not None:
                        out.add(int(local))
        return out


def share_crack_paths(groups: list, nodes: np.ndarray) -> None:
    """Make the EDE groups of a model share one crack-path registry (crack tracking across regions)."""
    if groups:
        paths = CrackPaths(nodes, groups)
        for g in groups:
            g._paths = paths


class EmbeddedDruckerPrager(DruckerPragerSolid):
    """Drucker-Prager cells that localize into embedded discontinuities (one jump per cell)."""

    checkpoint_attrs = ("state", "sigma", "dissipated", "crack_dissipated", "surface_dissipated", "e_state",
                        "gradf", "active", "anchor", "segments", "last_event", "crack_count")

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

    @property
    def crack_count(self) -> int:
        return self.paths.cracks

    @crack_count.setter
    def crack_count(self, value: int) -> None:
        self.paths.cracks = value

    kind = "embedded"

    def __init__(self, nodes: np.ndarray, cells: np.ndarray, ref: ReferenceElement, law: DruckerPrager,
                 surface: EmbeddedLaw, band: str = "positive", plane_strain: bool = True, tracking: str = "none",
                 max_cracks: int = 1, *, region: str = "bulk", cell_ids: np.ndarray | None = None):
        super().__init__(nodes, cells, ref, law, region=region, cell_ids=cell_ids)
        self._paths: CrackPaths | None = None
        self.crack_dissipated = 0.0  # the embedded jumps' share of ``dissipated`` [J]
        self.surface_dissipated = 0.0  # sum of |S| <T> . dJ: the traction law's work on the surfaces (2D) [J]
        if band not in ("positive", "negative"):
            raise ValueError(f"band must be 'positive' or 'negative', got {band!r}")
        if tracking not in ("none", "local"):
            raise ValueError(f"tracking must be 'none' or 'local', got {tracking!r}")
        self.tracking = tracking
        self.max_cracks = max_cracks  # tracking = "local": most cracks started (the others are continued)
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
        self.nodes = nodes
        if tracking == "local" and self.dim != 2:
            raise ValueError("tracking = 'local' follows crack paths in 2D meshes only")
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

    # -- state -----------------------------------------------------------------------------
    def begin_step(self) -> None:
        super().begin_step()
        self.e_trial[:] = self.e_state
        self._dz[:] = 0.0
        self._k_prev[:] = 0.0
        self._flips[:] = 0
        self._stuck[:] = False
        self._released[:] = False

    def commit(self) -> None:
        work = self._crack_work()
        self.crack_dissipated += work
        self.dissipated += work
        self.surface_dissipated += self._surface_work()
        super().commit()
        self.e_state[:] = self.e_trial
        self.last_event = self._localize()

    def _surface_work(self) -> float:
        """The traction law's work over the step on the cut cells' surfaces (2D: length |S| of each
        segment; 0 in 3D, where the surface's area is not kept): |S| <T> . dJ with T = q t + P n the
        averaged traction (trapezoidal in time) [J]. In an exact formulation it equals
        :meth:`_crack_work`; this element's constant jump and volume-averaged traction make them differ."""
        if self.dim != 2:
            return 0.0
        old, new = self.e_state, self.e_trial
        d_j = new[:, K.E_J:K.E_J + 3] - old[:, K.E_J:K.E_J + 3]
        cut = np.flatnonzero(np.any(d_j != 0.0, axis=1))
        if not cut.size:
            return 0.0
        length = np.linalg.norm(self.segments[cut, 1] - self.segments[cut, 0], axis=1)

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
        threads.serial_below(self.grads.shape[0], threads.SOLID_CELLS, K.ede_blocks, self.grads, self.wdet, d,
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

    # -- bifurcation and localization ------------------------------------------------------
    def _candidates(self, state: np.ndarray) -> np.ndarray:
        """Cells not yet localized with a Gauss point on the cone in the last update (with local
        tracking, the crack-tip cells are added whatever their state: see _scan)."""
        plastic = (state[..., S_MODE] == MODE_CONE).any(axis=1)
        return np.flatnonzero(plastic & (self.e_trial[:, K.E_LOC] == 0.0))

    def committed_event(self) -> float:
        """Min det A / det A^e of the committed state over cells that may still localize."""
        return self.last_event

    def event(self) -> float:
        """Min det A / det A^e (eq. 7-8) over the trial (converged, uncommitted) plastic points of
        cells that may still localize; 1 if there are none."""
        return self._scan(self.trial, self.trial_sigma, exact_cells=False)[0]

    SCREEN_SWEEP = 90  # in-plane normals of the compiled screen (plane strain)
    SCREEN_MARGIN = 0.05  # points whose screened ratio is below this get the exact search

    def _scan(self, state: np.ndarray, sigma: np.ndarray, eligible: np.ndarray | None = None,
              exact_cells: bool = True):
        """Min det ratio over the plastic points of cells that may localize, and per such cell its
        lowest (ratio, point, Localization).

        Plane strain: a compiled sweep screens every point; the exact search (localization_at) runs
        at the lowest screened point overall (the returned minimum, exact where it can be near zero)
        and, if exact_cells, at the lowest point of every eligible cell (default: all) screened below
        SCREEN_MARGIN -- where an onset can happen.
        """
        cells = self._candidates(state)
        tips = self._tip_cells() if self.tracking == "local" else np.zeros(0, dtype=np.int64)
        cells = np.union1d(cells, tips).astype(np.int64)
        if cells.size == 0:
            return 1.0, {}
        qmask = state[cells, :, S_MODE] == MODE_CONE
        qmask[np.isin(cells, tips)] = True  # a crack tip cell: its stress direction decides (eq. 8)
        ce, qi = np.nonzero(qmask)
        e_of = cells[ce]
        if e_of.size == 0:
            return 1.0, {}
        if not self.plane_strain:  # 3D: the exact search at every point
            screened = np.full(e_of.size, -np.inf)
        else:
            screened = screen_plane_strain(np.ascontiguousarray(sigma[e_of, qi]), self.p, self.ce,
                                           self.SCREEN_SWEEP)
        order = np.lexsort((screened, e_of))  # by cell, lowest point first
        first = order[np.concatenate(([True], e_of[order][1:] != e_of[order][:-1]))]
        lowest = first[screened[first] <= self.SCREEN_MARGIN]  # each cell's lowest point, if small
        if eligible is not None:
            lowest = lowest[np.isin(e_of[lowest], eligible)]
        lowest_point = int(np.argmin(screened))
        chosen = set(lowest.tolist()) if exact_cells else set()
        chosen.add(lowest_point)
        picks = sorted(chosen)
        where: dict[int, tuple] = {}
        best = float(screened.min())
        if self.plane_strain:  # the exact minima of all picks in one compiled pass; the full
            # Localization (normals, slips) only where a cell can open now
            ratios = min_ratios_plane_strain(self.law, sigma[e_of[picks], qi[picks]])
        else:
            locs = [localization_at(self.law, sigma[int(e_of[k]), int(qi[k])], plane_strain=False) for k in picks]
            ratios = np.array([loc.min_ratio for loc in locs])
        for n_pick, k in enumerate(picks):
            e, q, ratio = int(e_of[k]), int(qi[k]), float(ratios[n_pick])
            best = min(best, ratio) if k == lowest_point else best
            if screened[k] <= self.SCREEN_MARGIN and ratio < where.get(e, (np.inf,))[0]:
                where[e] = (ratio, q, None if self.plane_strain else locs[n_pick])
        for e, (ratio, q, loc) in where.items():
            if loc is None and ratio <= self.onset_tol:
                where[e] = (ratio, q, localization_at(self.law, sigma[e, q], plane_strain=True))
        if where:
            best = min(best, min(v[0] for v in where.values()))
        return best, where

    onset_tol = 1e-4  # localize when min det A / det A^e <= this (the stepping lands within it)

    def _localize(self) -> float:
        """Localize the cells whose committed state has det A / det A^e <= onset_tol; returns the min
        det ratio over the cells that may still localize (1 if none).

        tracking = "none": each such cell is cut through its centroid. "local" (2D): a cell next to a
        cut cell whose surface ends on their shared edge continues it from that point (the crack tip),
        with the conjugate normal closest to the neighbour's; a cell with no cut neighbour starts a
        new crack through its centroid; a cell beside a crack but not at its tip waits (it stays a
        Drucker-Prager cell) until the crack reaches it.
        """
        eligible = None
        if self.tracking == "local" and self.paths.cracks >= self.max_cracks:
            eligible = self._tip_cells()  # only crack tips can open: no new crack allowed
        best, where = self._scan(self.state, self.sigma, eligible)
        ready = sorted((ratio, e) for e, (ratio, q, loc) in where.items() if ratio <= self.onset_tol)
        if self.tracking == "none":
            for ratio, e in ready:
                self._open(e, ratio, where[e][2])
            return best
        pending = [e for _, e in ready]
        tips = set(self._tip_cells().tolist())
        progress = True
        while pending and progress:  # a newly cut cell may give the next one its tip...
            progress = False
            for e in list(pending):
                tip = self._tip(e)
                plastic = (self.state[e, :, S_MODE] == MODE_CONE).any()
                if tip is not None and e not in tips and not plastic:
                    continue  # ...but an elastic cell only from a tip that existed before this step
                if tip is None and (self._cut_neighbours(e) or self.paths.cracks >= self.max_cracks):
                    continue  # beside a crack but not at its tip, or no new crack allowed: wait
                if tip is None:
                    self.paths.cracks += 1
                self._open(e, where[e][0], where[e][2], tip)
                pending.remove(e)
                progress = True
        return best

    # -- crack path (2D) ---------------------------------------------------------------------
    @property
    def paths(self) -> CrackPaths:
        """The crack-path registry this group shares with the other EDE groups of the model."""
        if self._paths is None:
            self._paths = CrackPaths(self.nodes, [self])
        return self._paths

    def _global(self, e: int) -> int:
        return int(self.cell_ids[e])

    def _tip_cells(self) -> np.ndarray:
        """This group's uncut cells where a cut cell's surface ends on their shared edge (crack tips)."""
        return np.array(sorted(self.paths.tip_cells(self)), dtype=np.int64)

    def _cut_neighbours(self, e: int) -> list[int]:
        return self.paths.cut_neighbours(self._global(e))

    def _tip(self, e: int) -> tuple[np.ndarray, np.ndarray] | None:
        """(point, neighbour normal) where a cut neighbour's surface ends on the edge shared with e."""
        return self.paths.tip(self._global(e))

    def _choose(self, loc, reference: np.ndarray | None = None) -> tuple[np.ndarray, float]:
        """The normal of the requested conjugate band (band angle > 0 or < 0), or the one closest to a
        reference normal (a crack being continued), and the other's band angle."""
        angles = loc.band_angles
        ranked = sorted(range(len(angles)), key=lambda k: loc.ratios[k])[:2]
        if reference is not None:
            k = max(ranked, key=lambda j: abs(float(np.dot(loc.normals[j], reference))))
        else:
            want = [k for k in ranked if (angles[k] > 0) == (self.band == "positive")]
            k = want[0] if want else ranked[0]
        other = [j for j in ranked if j != k]
        return loc.normals[k], (float(angles[other[0]]) if other else math.nan)

    def _open(self, e: int, ratio: float, loc, tip=None) -> None:
        point, reference = tip if tip is not None else (None, None)
        n, other = self._choose(loc, reference)
        c_p = self.localize_cell(e, n, point=point)
        s = self.e_state[e]
        band = float(math.atan2(s[K.E_T + 1], s[K.E_T]))
        self.onsets.append(Onset(e, s[K.E_N:K.E_N + 3].copy(), band, ratio, c_p, other,
                                 np.asarray(loc.normals), np.asarray(loc.slips)))

    def localize_cell(self, e: int, normal: np.ndarray, c_p: float | None = None,
                      point: np.ndarray | None = None) -> float:
        """Cut cell e by the surface with this normal through ``point`` (default: the centroid);
        returns its c_p [Pa].

        n is signed to point up (the + side above, like the CSE's), t = (n_y, -n_x); active nodes
        (X_a - X_p) . n > 0; c_p from eq. (28) on the committed stress unless given (or set in the
        law). The cell's bulk is frozen from here on; its segment (the surface clipped to the cell,
        2D) is kept for the crack path and the output.
        """
        n = np.zeros(3)
        n[: len(normal)] = normal
        n /= np.linalg.norm(n)
        if n[1] < 0 or (n[1] == 0 and n[0] < 0):
            n = -n
        t = np.array([n[1], -n[0], 0.0])  # (t, n) right-handed in the x-y plane
        dim = self.dim
        xc = self.x[e].mean(axis=0) if point is None else np.asarray(point, dtype=float)[:dim]
        active = (self.x[e] - xc) @ n[:dim] > 0.0
        if active.all() or not active.any():
            raise RuntimeError(f"cell {e}: the surface through the centroid leaves no node on one side")
        self.gradf[e] = 0.0
        self.gradf[e, :, :dim] = self.grads[e][:, active, :].sum(axis=1)
        self.active[e] = active
        self.anchor[e, :dim] = xc
        if dim == 2:
            self.segments[e] = surface_segment(self.x[e], n[:2], xc)
        w = self.wdet[e] / self.wdet[e].sum()
        tr = np.einsum("q,qi->i", w, self.sigma[e])  # volume-averaged committed stress
        sig = np.array([[tr[0], tr[3], tr[5]], [tr[3], tr[1], tr[4]], [tr[5], tr[4], tr[2]]])
        q, p = t @ sig @ n, n @ sig @ n
        if c_p is None:
            tphi = math.tan(self.surface.phi_p)
            c_p = self.surface.c_p if self.surface.c_p is not None else abs(q) + tphi * min(p, 0.0)  # eq. (28)
        s = self.e_state[e]
        s[:] = 0.0
        s[K.E_LOC] = 1.0
        s[K.E_N:K.E_N + 3] = n
        s[K.E_T:K.E_T + 3] = t
        s[K.E_CP] = c_p
        s[K.E_Q], s[K.E_P] = q, p
        s[K.E_SIGN] = 1.0 if q >= 0 else -1.0
        self.e_trial[e] = s
        return float(c_p)

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

    # -- output ----------------------------------------------------------------------------
    def point_records(self, u: np.ndarray) -> dict[str, np.ndarray]:
        """:meth:`records` with the state named, the mesh's cell numbers and the region as the set."""
        rec = self.records()
        rec["state"] = np.where(rec["mode"] == 1.0, "plastic", "constrained")
        rec["cell"] = self.cell_ids[rec["cell"]]
        rec["set"] = np.full(rec["cell"].shape[0], self.region)
        return rec

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
        return {
            "cell": cells, "x": centre[:, 0], "y": centre[:, 1], "jump_t": jt, "jump_n": jn,
            "angle": np.arctan2(s[:, K.E_T + 1], s[:, K.E_T]),
            "T_t": s[:, K.E_Q], "T_n": s[:, K.E_P], "jump_p_t": jt, "jump_p_n": jn,
            "jump_p_norm": np.linalg.norm(j, axis=1), "gamma": s[:, K.E_GAMMA], "zeta": s[:, K.E_ZETA],
            "c": q[:, 0], "tan_phi": q[:, 1], "tan_psi": np.tan(q[:, 2]), "c_p": s[:, K.E_CP],
            "mode": s[:, K.E_MODE],
        }
