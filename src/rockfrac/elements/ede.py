"""Drucker-Prager bulk with embedded strong discontinuities (EDE, paper Sect. 3.1, 5; EDE_NOTES).

Every cell is a Drucker-Prager solid until, at the end of a converged step, the acoustic tensor
of eq. (7)-(8) at one of its plastic Gauss points loses ellipticity (min det A / det A^e <= 0).
The cell then localizes for good: a surface through its centroid with that normal (the conjugate
chosen by ``band``), c_p from eq. (28) on the converged stress, the bulk frozen elastic. See
:mod:`rockfrac.elements.ede_kernel` for the element equations.
"""

from __future__ import annotations

import math

import numpy as np

from rockfrac.elements import ede_kernel as K
from rockfrac.elements.ede_cells import EmbeddedCells, shear_directions
from rockfrac.elements.ede_paths import (
    CrackPaths,
    Onset,
    share_crack_paths,  # noqa: F401  (re-exported: the case builder imports it from here)
)
from rockfrac.fem.planes import in_plane_direction
from rockfrac.laws.bifurcation import localization_at, min_ratios_plane_strain
from rockfrac.laws.bifurcation_plane import screen_plane_strain
from rockfrac.laws.bifurcation_dp3d import min_ratios_dp_3d
from rockfrac.laws.drucker_prager_params import MODE_CONE, S_MODE
from rockfrac.mesh.geometry import surface_segment


class EmbeddedDruckerPrager(EmbeddedCells):
    """Drucker-Prager cells that localize into embedded discontinuities (one jump per cell)."""

    @property
    def crack_count(self) -> int:
        return self.paths.cracks

    @crack_count.setter
    def crack_count(self, value: int) -> None:
        self.paths.cracks = value

    def commit(self) -> None:
        work = self._crack_work()
        self.crack_dissipated += work
        self.dissipated += work
        self.surface_dissipated += self._surface_work()
        super().commit()
        self.e_state[:] = self.e_trial
        self.last_event = self._localize()

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
        if not self.tip_events:
            return self._scan(self.trial, self.trial_sigma, exact_cells=False, trial=True)[0]
        return self._scan(self.trial, self.trial_sigma, self._eligible(), exact_cells=False, trial=True)[0]

    def growth_waiting(self) -> bool:
        """True if the last commit cut cells, or cells at the tips it made wait for the stress after
        its cuts (tip events only: the nodal crack)."""
        return bool(self.deferred.any())

    #: the event indicator over the cells that may open next only (:meth:`_eligible`), so that every
    #: crack tip's onset is located; the elemental EDE keeps its first version's (every candidate)
    tip_events = False

    def _eligible(self, waiting: bool = False) -> np.ndarray | None:
        """The cells that may open next: every one (None) while a new crack may start, else the crack
        tips (a cell beside a crack waits for its tip, so it is no event); with tip events, less the
        cells that wait for the stress after the last commit's cuts (at a tip made by them, ready on
        the stress before them): they are no event of the next step, which is a hold at the same load
        (rockfrac.solve.stepping), and its commit takes them again (``waiting``: with them)."""
        if self.tracking == "none":
            return None
        cells = self._tip_cells() if self.paths.cracks >= self.max_cracks else None
        if not self.tip_events:
            return cells
        if waiting or not self.deferred.any():
            return cells
        if cells is None:
            cells = np.arange(self.cells.shape[0])
        return cells[~self.deferred[cells]]

    SCREEN_SWEEP = 90  # in-plane normals of the compiled screen (plane strain)
    SCREEN_MARGIN = 0.05  # points whose screened ratio is below this get the exact search

    def _scan(self, state: np.ndarray, sigma: np.ndarray, eligible: np.ndarray | None = None,
              exact_cells: bool = True, trial: bool = False):
        """Min det ratio over the plastic points of cells that may localize, and per such cell its
        lowest (ratio, point, Localization).

        Plane strain: a compiled sweep screens every point; the exact search (localization_at) runs
        at the lowest screened point overall (the returned minimum, exact where it can be near zero)
        and, if exact_cells, at the lowest point of every eligible cell (default: all) screened below
        SCREEN_MARGIN -- where an onset can happen. General 3D: every point's minimum is exact, in
        closed form (rockfrac.laws.bifurcation_dp3d). The full Localization (normals, slips) is made
        only where a cell can open now. trial: state and sigma are the step's trial ones (the nonlocal
        stress at the tips is then the trial one too).
        """
        cells = self._candidates(state)
        tips = self._tip_cells() if self.tracking != "none" else np.zeros(0, dtype=np.int64)
        cells = np.union1d(cells, tips).astype(np.int64)
        if eligible is not None and self.tip_events:  # the indicator and onsets over the cells that may open
            cells = np.intersect1d(cells, eligible)
        near = self._tip_stresses(trial) if self.tracking == "nonlocal" else {}
        e_of, qi, screened = np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64), np.zeros(0)
        if cells.size:
            qmask = state[cells, :, S_MODE] == MODE_CONE
            at_tip = np.isin(cells, tips)
            qmask[at_tip] = True  # a crack tip cell: its stress direction decides (eq. 8)...
            if self.tracking == "nonlocal" and tips.size:  # ...or the nonlocal stress at its tip point,
                extra = sigma[:, :1].copy()  # as one more point of the cell
                for e in tips:
                    stress = near.get(self._global(int(e)))
                    if stress is not None and np.all(np.isfinite(stress)):
                        extra[e, 0] = stress
                sigma = np.concatenate([sigma, extra], axis=1)
                qmask = np.concatenate([qmask, at_tip[:, None]], axis=1)
            ce, qi = np.nonzero(qmask)
            e_of = cells[ce]
        if e_of.size:
            points = np.ascontiguousarray(sigma[e_of, qi])
            screened = (screen_plane_strain(points, self.p, self.ce, self.SCREEN_SWEEP) if self.plane_strain
                        else min_ratios_dp_3d(points, self.p))  # 3D: the exact minima
        lowest_point = self._global_lowest(screened, e_of, qi)
        if e_of.size == 0:
            return 1.0, {}
        order = np.lexsort((screened, e_of))  # by cell, lowest point first
        first = order[np.concatenate(([True], e_of[order][1:] != e_of[order][:-1]))]
        lowest = first[screened[first] <= self.SCREEN_MARGIN]  # each cell's lowest point, if small
        if eligible is not None:
            lowest = lowest[np.isin(e_of[lowest], eligible)]
        chosen = set(lowest.tolist()) if exact_cells else set()
        if lowest_point is not None:
            chosen.add(lowest_point)
        if not chosen:  # on another rank: the lowest point and every cell that may open
            return float(screened.min()), {}
        picks = sorted(chosen)
        where: dict[int, tuple] = {}
        best = float(screened.min())
        # the exact minima of all picks in one compiled pass (3D: the screen's); the full Localization
        # (normals, slips) only where a cell can open now
        ratios = (min_ratios_plane_strain(self.law, sigma[e_of[picks], qi[picks]]) if self.plane_strain
                  else screened[picks])
        for n_pick, k in enumerate(picks):
            e, q, ratio = int(e_of[k]), int(qi[k]), float(ratios[n_pick])
            best = min(best, ratio) if k == lowest_point else best
            if screened[k] <= self.SCREEN_MARGIN and ratio < where.get(e, (np.inf,))[0]:
                where[e] = (ratio, q, None)
        for e, (ratio, q, loc) in where.items():
            if loc is None and ratio <= self.onset_tol:
                where[e] = (ratio, q, localization_at(self.law, sigma[e, q], plane_strain=self.plane_strain))
        if where:
            best = min(best, min(v[0] for v in where.values()))
        return best, where

    def _tip_stresses(self, trial: bool = False) -> dict[int, np.ndarray]:
        """The nonlocal stress at the tip point of every crack-tip cell of the group (any rank's, by
        whole mesh id; a collective call, one per tip in the serial order)."""
        paths = self.paths
        return {gcell: paths.nonlocal_stress(point, self._nonlocal_length(), trial)
                for gcell, point in paths.tips_everywhere(self)}

    def _global_lowest(self, screened: np.ndarray, e_of: np.ndarray, qi: np.ndarray) -> int | None:
        """Index in e_of of the group's lowest screened point over every MPI rank, if this rank holds
        it, else None (one process: the argmin). A collective call: every rank makes it."""
        mine = None
        if e_of.size:
            j = int(np.argmin(screened))
            mine = (float(screened[j]), int(self.serial_index[e_of[j]]), int(qi[j]))
        held = [v for v in self.paths.exchange.allgather(mine) if v is not None]
        return j if mine is not None and min(held) == mine else None

    def _nonlocal_length(self) -> float:
        """tracking = "nonlocal": the Gaussian length of the stress average at a tip [m]."""
        assert self.tracking_length is not None  # checked at construction
        return self.tracking_length

    onset_tol = 1e-4  # localize when min det A / det A^e <= this (the stepping lands within it)

    def _localize(self) -> float:
        """Localize the cells whose committed state has det A / det A^e <= onset_tol; returns the min
        det ratio over the cells that may still localize (1 if none).

        tracking = "none": each such cell is cut through its centroid. "local" (2D): a cell next to a
        cut cell whose surface ends on their shared edge continues it from that point (the crack tip),
        with the conjugate normal closest to the neighbour's; a cell with no cut neighbour starts a
        new crack through its centroid; a cell beside a crack but not at its tip waits (it stays a
        Drucker-Prager cell) until the crack reaches it. "nonlocal": as "local", but the tip
        cell also opens where the nonlocal stress at its tip point (:meth:`CrackPaths.nonlocal_stress`)
        loses ellipticity, and takes the normal of that stress.
        """
        paths = self.paths
        if self.tracking != "none":
            paths.current()
        best, where = self._scan(self.state, self.sigma, self._eligible(waiting=True))
        ready = sorted((ratio, e) for e, (ratio, q, loc) in where.items() if ratio <= self.onset_tol)
        if self.tracking == "none":
            for ratio, e in ready:
                self._open(e, ratio, where[e][2])
            return best
        # the same decisions on every rank: the cells ready on any rank, in the serial order; whether
        # a cell was at a crack tip before this step's cuts, as its owner saw it
        mine = [(ratio, int(self.serial_index[e]), self._global(e),
                 bool((self.state[e, :, S_MODE] == MODE_CONE).any()), where[e][2],
                 paths.tip(self._global(e)) is not None) for ratio, e in ready]
        pending = sorted((c for part in paths.exchange.allgather(mine) for c in part), key=lambda c: c[:2])
        any_ready = bool(pending)  # on any rank (the scan below is collective)
        k = paths.groups.index(self)
        waited = self.deferred.copy()  # through the hold that ends here
        self.deferred[:] = False
        opened = []
        progress = True
        while pending and progress:  # a newly cut cell may give the next one its tip...
            progress = False
            for cand in list(pending):
                ratio, _, gcell, plastic, loc, was_tip = cand
                tip, beside = paths.at_owner(gcell, lambda c: (paths.tip(c), bool(paths.cut_neighbours(c))))
                if tip is not None and not was_tip and not plastic:
                    continue  # ...but an elastic cell only from a tip that existed before this step
                if tip is None and (beside or paths.cracks >= self.max_cracks):
                    continue  # beside a crack but not at its tip, or no new crack allowed: wait
                if tip is None:
                    paths.cracks += 1
                normal = None  # "nonlocal": the tip's nonlocal stress decides (a collective call)
                if tip is not None and self.tracking == "nonlocal":
                    normal = paths.nonlocal_normal(self, tip[0], tip[1], self._nonlocal_length())
                local = paths.local(gcell, k)
                if local >= 0:
                    self._open(local, ratio, loc, tip, normal)
                    opened.append(local)
                paths.announce(gcell)
                self.cut_announced(gcell)
                pending.remove(cand)
                progress = True
        if not any_ready or not self.tip_events:
            return best
        # the next step is a hold at this load, for the cells cut now (the stress they release) and
        # for those that wait for the stress after the cuts: the ready ones that could not open (an
        # elastic cell at a new tip), and the new tips ready on the stress before the cuts; a cell
        # that waited through the last hold and still did not open waits no more (an onset in a
        # later step is located as an event)
        paths.current()
        after = self._scan(self.state, self.sigma, self._eligible(waiting=True))[1]
        wait = {paths.local(c[2], k) for c in pending} | {e for e, v in after.items() if v[0] <= self.onset_tol}
        self.deferred[[e for e in sorted(wait) if e >= 0 and not waited[e]] + opened] = True
        # the indicator over the cells that may open next: an onset in the next step is an event
        return self._scan(self.state, self.sigma, self._eligible(), exact_cells=False)[0]

    def cut_announced(self, gcell: int) -> None:
        """Called on every rank, in the same order, after mesh cell gcell (of this group, on any rank)
        was cut and its surface announced (a nodal crack enters it in its enrichment)."""

    # -- crack path (2D) ---------------------------------------------------------------------
    @property
    def paths(self) -> CrackPaths:
        """The crack-path registry this group shares with the other EDE groups of the model."""
        if self._paths is None:  # a registry of its own (cells cut before it existed entered at once)
            self._paths = CrackPaths(self.nodes, [self])
            self._paths.sync()
        return self._paths

    def _global(self, e: int) -> int:
        """Cell e's index in the whole mesh (the crack-path registry's name for it)."""
        return int(self.whole_ids[e])

    def _tip_cells(self) -> np.ndarray:
        """This group's uncut cells where a cut cell's surface ends on their shared edge (crack tips)."""
        self.paths.current()
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

    def _open(self, e: int, ratio: float, loc, tip=None, normal: np.ndarray | None = None) -> None:
        """Cut cell e: through the tip (a crack continued) or its centroid, with the conjugate normal
        closest to the crack's, or ``normal`` (tracking "nonlocal", from the stress at the tip)."""
        point, reference = tip if tip is not None else (None, None)
        n, other = self._choose(loc, reference)
        if normal is not None:
            n = normal
        c_p = self.localize_cell(e, n, point=point)
        s = self.e_state[e]
        band = float(math.atan2(s[K.E_T + 1], s[K.E_T]))
        self.onsets.append(Onset(int(self.serial_index[e]), s[K.E_N:K.E_N + 3].copy(), band, ratio, c_p, other,
                                 np.asarray(loc.normals), np.asarray(loc.slips)))

    def localize_cell(self, e: int, normal: np.ndarray, c_p: float | None = None,
                      point: np.ndarray | None = None) -> float:
        """Cut cell e by the surface with this normal through ``point`` (default: the centroid);
        returns its c_p [Pa].

        n is signed to point up (the + side above, like the CSE's), t = (n_y, -n_x); active nodes
        (X_a - X_p) . n > 0; c_p from eq. (28) on the committed stress unless given (or set in the
        law; at least 0). The cell's bulk is frozen from here on; its segment (the surface clipped to the cell,
        2D) is kept for the crack path and the output.
        """
        n = np.zeros(3)
        n[: len(normal)] = normal
        n /= np.linalg.norm(n)
        general = not self.plane_strain and self.dim == 3
        if general:  # a general 3D body: n points up in z (then y, then x)
            if next(v for v in n[::-1] if v != 0.0) < 0.0:
                n = -n
        elif n[1] < 0 or (n[1] == 0 and n[0] < 0):
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
            if self._paths is not None:  # the crack-path registry's table (a shared registry)
                self._paths.record(self._global(e), self.segments[e], n)
        elif general:
            if self._paths is not None:  # the crack-path registry's table: a point of the plane
                self._paths.record(self._global(e), xc.copy(), n)
        elif self.x.shape[1] == 8 and abs(n[2]) <= 1e-12 and np.ptp(self.x[e, :4, 2]) <= 1e-12 * np.ptp(self.x[e]):
            self.sections[e] = surface_segment(self.x[e, :4, :2], n[:2], xc[:2])  # plane strain: the z face's trace
        w = self.wdet[e] / self.wdet[e].sum()
        tr = np.einsum("q,qi->i", w, self.sigma[e])  # volume-averaged committed stress
        sig = np.array([[tr[0], tr[3], tr[5]], [tr[3], tr[1], tr[4]], [tr[5], tr[4], tr[2]]])
        if general:  # t along the shear traction on the surface (frozen with n; q = |shear| >= 0)
            shear, _, ok = shear_directions(sig[None], n[None])
            t = shear[0] if ok[0] else in_plane_direction(n[None])[0]
        q, p = t @ sig @ n, n @ sig @ n
        if c_p is None:
            tphi = math.tan(self.surface.phi_p)
            # eq. (28); never below 0: a cell whose traction is inside the friction cone (a crack tip cut
            # by the nonlocal stress) gets a purely frictional surface, not a negative cohesion
            c_p = self.surface.c_p if self.surface.c_p is not None else max(abs(q) + tphi * min(p, 0.0), 0.0)
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
