"""Localization onsets and the crack-path registry (cell adjacency, cut cells, tips) of the EDE groups."""

from __future__ import annotations

import math
from dataclasses import dataclass
from collections.abc import Callable
from typing import Any, Protocol

import numpy as np

from rockfrac.elements import ede_kernel as K
from rockfrac.fem.planes import EDGES, plane_polygons
from rockfrac.laws.bifurcation import localization_at
from rockfrac.laws.bifurcation_plane import MAX_MINIMA, minima_plane_strain
from rockfrac.mesh.topology import HEX_FACES, TET_FACES


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


# the sides of a 3D cell by its node count (VTK order): a hexahedron's six faces
SIDES = {8: HEX_FACES, 4: TET_FACES}  # a 3D cell's faces, by its number of nodes
CELL_OF_NODES = {8: "hex8", 4: "tet4"}


class Exchange(Protocol):
    """How the ranks of a distributed model share what each holds (rockfrac.model.Model.allgather)."""

    def allgather(self, value: Any) -> list[Any]: ...


class Alone:
    """The exchange of a model on one process: each value is everyone's."""

    def allgather(self, value: Any) -> list[Any]:
        return [value]


class CrackPaths:
    """Crack paths across the EDE groups of a model (2D, and hexahedra of a general 3D body): cell
    adjacency (shared edges; in 3D shared faces), the cut state of the cells, the number of cracks
    started.

    Cells are named by their index in the whole mesh. A registry sees the cells of ``full``: each
    group's cells as (whole mesh ids, connectivity in ``nodes``' numbering); default, the groups'
    own cells. On one process that is every cell. On several
    MPI ranks it is the rank's own cells and every cell that shares a side with one (its halo), so
    that everything an own cell's tracking needs is at hand: its neighbours, their surfaces, the
    nodes of the sides between them.

    The cut cells' surfaces (segment and normal) are kept in a table over the cells seen, filled
    from the groups that cut them: on one process as they cut them; on several ranks each cut is
    announced by its owner (:meth:`announce`), so that the table agrees on every rank where the
    ranks see the same cell. Tracking decisions are taken alike on every rank, each fact about a
    cell asked of its owner (:meth:`at_owner`; rockfrac.elements.ede)."""

    def __init__(self, nodes: np.ndarray, groups: list,
                 full: list[tuple[np.ndarray, np.ndarray]] | None = None, exchange: Exchange | None = None):
        self.nodes = nodes
        self.groups = groups
        self.cracks = 0
        self.exchange: Exchange = exchange if exchange is not None else Alone()
        self.stale = False  # the table must be rebuilt from the groups (after a checkpoint's restore)
        if full is None:
            full = [(g.whole_ids, g.cells) for g in groups]
        if len(full) != len(groups):
            raise ValueError(f"{len(full)} cell lists for {len(groups)} groups")
        ids = np.concatenate([np.asarray(i, dtype=np.int64) for i, _ in full] + [np.zeros(0, dtype=np.int64)])
        order = np.argsort(ids, kind="stable")
        self.ids = ids[order]  # the whole mesh's id of every cell seen, ascending (their slots)
        if self.ids.size > 1 and np.any(self.ids[1:] == self.ids[:-1]):
            raise ValueError("a cell is in two EDE groups")
        slot_of = np.empty_like(order)
        slot_of[order] = np.arange(order.size)
        n = self.ids.size
        self.owner = np.full((n, 2), -1, dtype=np.int64)  # (group, local cell) of each own cell
        for k, g in enumerate(groups):
            own = self.slots(g.whole_ids)
            self.owner[own, 0], self.owner[own, 1] = k, np.arange(own.size)
        self.cut = np.zeros(n, dtype=bool)  # the table of cut cells
        self.segment = np.full((n, 2, 2), np.nan)  # 2D: their surfaces clipped to the cells [m]
        self.anchor = np.full((n, 3), np.nan)  # 3D: a point of their planes [m]
        self.normal = np.zeros((n, 3))
        self.centres = [g.x.mean(axis=1) for g in groups]  # own cell centroids per group [m]
        self._tips: dict[int, tuple[np.ndarray, np.ndarray] | None] = {}  # tip() by slot, until the table changes
        self.nbr: dict[int, list[tuple[int, tuple[int, ...]]]] = {}  # by slot: (neighbour's slot, shared nodes)
        if n == 0:
            return
        conn = np.vstack([c for _, c in full if len(c)])
        self.cell_nodes = np.empty((n, conn.shape[1]), dtype=np.int64)  # every seen cell's nodes
        self.cell_nodes[slot_of] = conn
        sides = SIDES.get(conn.shape[1]) if nodes.shape[1] == 3 else None  # 3D: faces; 2D: edges
        if sides is None:
            sides = np.stack([np.arange(conn.shape[1]), np.roll(np.arange(conn.shape[1]), -1)], axis=1)
        pairs = conn[:, sides].reshape(-1, sides.shape[1])
        owner = np.repeat(slot_of, sides.shape[0])
        key = np.sort(pairs, axis=1)
        by_side = np.lexsort(key.T[::-1])
        ks = key[by_side]
        for i in np.flatnonzero(np.all(ks[1:] == ks[:-1], axis=1)):  # once, at set-up
            c1, c2 = int(owner[by_side[i]]), int(owner[by_side[i + 1]])
            shared = tuple(int(v) for v in ks[i])
            self.nbr.setdefault(c1, []).append((c2, shared))
            self.nbr.setdefault(c2, []).append((c1, shared))

    def slots(self, gcells) -> np.ndarray:
        """The slots of cells seen here (whole mesh ids); -1 for a cell not seen."""
        gcells = np.asarray(gcells, dtype=np.int64)
        at = np.minimum(np.searchsorted(self.ids, gcells), max(self.ids.size - 1, 0))
        found = self.ids[at] == gcells if self.ids.size else np.zeros(gcells.shape, dtype=bool)
        return np.where(found, at, -1)

    def _slot(self, gcell: int) -> int:
        """The slot of one cell (-1: not seen here)."""
        i = int(np.searchsorted(self.ids, gcell))
        return i if i < self.ids.size and self.ids[i] == gcell else -1

    def _cell(self, gcell: int):
        s = self._slot(gcell)
        g, local = self.owner[s] if s >= 0 else (-1, -1)
        return (None, -1) if g < 0 else (self.groups[g], int(local))

    def owns(self, gcell: int) -> bool:
        """Whether cell gcell is one of this registry's groups' own cells (this rank's)."""
        return self._cell(gcell)[0] is not None

    def local(self, gcell: int, k: int) -> int:
        """The index of cell gcell in group k, if it is this rank's cell of group k, else -1."""
        s = self._slot(gcell)
        return int(self.owner[s, 1]) if s >= 0 and self.owner[s, 0] == k else -1

    # -- the table of cut cells -------------------------------------------------------------------
    def record(self, gcell: int, surface: np.ndarray, normal: np.ndarray) -> None:
        """Enter a cut cell's surface in the table: its segment (2, 2) in 2D, a point of its plane
        (3,) in 3D [m]. A cell not seen here (another rank's, away from this rank's) is skipped."""
        s = self._slot(gcell)
        if s < 0:
            return
        self.cut[s] = True
        self._tips.clear()
        if np.shape(surface) == (3,):
            self.anchor[s] = surface
        else:
            self.segment[s] = surface
        self.normal[s] = normal

    @staticmethod
    def _surface(g, local):
        """A group's record of its cut cells' surfaces: segments (2D), plane points (3D)."""
        return g.segments[local] if g.dim == 2 else g.anchor[local]

    def announce(self, gcell: int) -> None:
        """Every rank: enter the cut of cell gcell as its owner holds it (a collective call)."""
        g, local = self._cell(gcell)
        mine = None if g is None else (self._surface(g, local).copy(), g.e_state[local, K.E_N:K.E_N + 3].copy())
        held = [v for v in self.exchange.allgather(mine) if v is not None]
        if len(held) != 1:
            raise RuntimeError(f"cell {gcell} is held by {len(held)} ranks, not one")
        self.record(gcell, *held[0])

    def at_owner(self, gcell: int, fact: Callable[[int], Any]) -> Any:
        """fact(gcell) as the rank owning cell gcell finds it, on every rank (a collective call; one
        process: fact(gcell)). Only the owner sees every neighbour of its cells."""
        mine = (fact(gcell),) if self.owns(gcell) else None
        held = [v for v in self.exchange.allgather(mine) if v is not None]
        if len(held) != 1:
            raise RuntimeError(f"cell {gcell} is held by {len(held)} ranks, not one")
        return held[0][0]

    def sync(self) -> None:
        """Rebuild the table from every rank's groups (a collective call)."""
        mine = []
        for g in self.groups:
            loc = np.flatnonzero(g.e_state[:, K.E_LOC] == 1.0)
            mine.append((g.whole_ids[loc], self._surface(g, loc), g.e_state[loc, K.E_N:K.E_N + 3]))
        self.cut[:] = False
        self._tips.clear()
        self.segment[:] = np.nan
        self.anchor[:] = np.nan
        self.normal[:] = 0.0
        for part in self.exchange.allgather(mine):
            for ids, surface, normal in part:
                s = self.slots(ids)
                seen = s >= 0
                s, surface, normal = s[seen], surface[seen], normal[seen]
                self.cut[s], self.normal[s] = True, normal
                if surface.ndim == 2 and surface.shape[1] == 3:
                    self.anchor[s] = surface
                else:
                    self.segment[s] = surface
        self.stale = False

    def current(self) -> None:
        """The table brought up to date where it is stale (every rank restored a checkpoint)."""
        if self.stale:
            self.sync()

    # -- tracking (of a cell seen with all its neighbours: an own cell) ----------------------------
    def is_cut(self, gcell: int) -> bool:
        s = self._slot(gcell)
        return bool(s >= 0 and self.cut[s])

    def cut_neighbours(self, gcell: int) -> list[int]:
        """The cut neighbours of cell gcell (whole mesh ids)."""
        return [int(self.ids[c]) for c, _ in self.nbr.get(self._slot(gcell), []) if self.cut[c]]

    def tip(self, gcell: int) -> tuple[np.ndarray, np.ndarray] | None:
        """(point, neighbour normal) where a cut neighbour's surface ends on the side shared with
        gcell: in 2D the end of its segment on the shared edge; in 3D the middle of the edge its
        polygon leaves on the shared face (the crack front there). Memoized until the table changes."""
        s = self._slot(gcell)
        return None if s < 0 else self._tip_at(s)

    def _tip_at(self, s: int) -> tuple[np.ndarray, np.ndarray] | None:
        """:meth:`tip` of the cell in slot s."""
        if s not in self._tips:
            self._tips[s] = self._tip_3d(s) if self.nodes.shape[1] == 3 else self._tip_2d(s)
        found = self._tips[s]
        return None if found is None else (found[0].copy(), found[1].copy())

    def _tip_2d(self, s: int) -> tuple[np.ndarray, np.ndarray] | None:
        for c, (a, b) in self.nbr.get(s, []):
            if not self.cut[c]:
                continue
            xa, xb = self.nodes[a, :2], self.nodes[b, :2]
            size = np.linalg.norm(xb - xa)
            for p in self.segment[c]:  # p on edge ab: collinear, between its ends
                cross = abs((xb[0] - xa[0]) * (p[1] - xa[1]) - (xb[1] - xa[1]) * (p[0] - xa[0])) / size
                along = np.dot(p - xa, xb - xa) / size**2
                if cross < 1e-9 * size and -1e-9 <= along <= 1 + 1e-9:
                    return p.copy(), self.normal[c].copy()
        return None

    def _tip_3d(self, s: int) -> tuple[np.ndarray, np.ndarray] | None:
        for c, face in self.nbr.get(s, []):
            if not self.cut[c]:
                continue
            conn = self.cell_nodes[c]
            verts, ends, _ = plane_polygons(self.nodes[conn][None], EDGES[CELL_OF_NODES[conn.shape[0]]],
                                            self.anchor[c][None], self.normal[c][None])
            ok = np.isfinite(verts[0]).all(axis=1)
            on = ok & np.isin(conn[np.where(ok[:, None], ends[0], 0)], face).all(axis=1)
            if on.sum() >= 2:
                return verts[0, on].mean(axis=0), self.normal[c].copy()
        return None

    def tip_cells(self, group) -> set[int]:
        """Local indices in ``group`` of its uncut own cells at a crack tip."""
        k = self.groups.index(group)
        out = set()
        for s in np.flatnonzero(self.cut).tolist():
            for c, _ in self.nbr.get(s, []):
                g, e = self.owner[c]
                if g == k and e not in out and not self.cut[c] and self._tip_at(c) is not None:
                    out.add(int(e))
        return out

    def tips_everywhere(self, group) -> list[tuple[int, np.ndarray]]:
        """Every rank's crack-tip cells of ``group`` with their tip points, as (whole id, point), in
        the group's serial order (a collective call)."""
        mine = []
        for e in sorted(self.tip_cells(group)):
            gcell = int(group.whole_ids[e])
            tip = self.tip(gcell)
            assert tip is not None
            mine.append((int(group.serial_index[e]), gcell, tip[0]))
        every = sorted((c for part in self.exchange.allgather(mine) for c in part), key=lambda c: c[0])
        return [(gcell, point) for _, gcell, point in every]

    def nonlocal_stress(self, point: np.ndarray, length: float, trial: bool = False) -> np.ndarray:
        """The nonlocal stress (6,) [Pa] at ``point`` (a crack tip): the average of the uncut cells'
        stresses with the Gaussian weight exp(-r^2 / (2 length^2)) of their centroids' distance r to
        the point (Wells & Sluys 2001), cut off at 3 length; NaN if no uncut cell is that close; the
        committed stresses, or the step's trial ones (``trial``). On several MPI ranks, a collective
        call: the sums over every rank's cells."""
        x = np.asarray(point, dtype=float)[:self.nodes.shape[1]]
        total, weight = np.zeros(6), 0.0
        for g, centre in zip(self.groups, self.centres):
            r2 = ((centre - x) ** 2).sum(axis=1)
            near = np.flatnonzero((r2 <= 9.0 * length**2) & (g.e_state[:, K.E_LOC] == 0.0))
            w = np.exp(-r2[near] / (2.0 * length**2))
            total += np.einsum("e,eq,eqi->i", w, g.wdet[near], (g.trial_sigma if trial else g.sigma)[near])
            weight += float(w @ g.wdet[near].sum(axis=1))
        parts = self.exchange.allgather((total, weight))  # every rank's cells (one process: its own)
        total, weight = parts[0]
        for t, w_r in parts[1:]:
            total, weight = total + t, weight + w_r
        return total / weight if weight > 0.0 else np.full(6, np.nan)

    def nonlocal_normal(self, group, point: np.ndarray, reference: np.ndarray, length: float) -> np.ndarray:
        """Normal (2,) in 2D, (3,) in 3D, that continues a crack from ``point`` (its tip, on the
        boundary of a cell of ``group``, whose law decides): of the conjugate bifurcation normals
        (eq. 7-8) of the nonlocal stress at the tip (:meth:`nonlocal_stress`; in 3D the two lowest
        minima of det A(n) / det A^e(n) on the unit sphere), the one closest to ``reference`` (the
        crack's last normal), signed like it.
        The direction comes from the stress the crack grows into, not from the singular field of the
        one cell at its tip. The tip cell's law gives the tangent."""
        g = group  # its law (the cell may be another rank's)
        dim = self.nodes.shape[1]
        ref = np.asarray(reference, dtype=float)[:dim]
        sigma = self.nonlocal_stress(point, length)[None, :]
        if not np.all(np.isfinite(sigma)):
            return ref / np.linalg.norm(ref)
        if dim == 3:
            loc = localization_at(g.law, sigma[0], plane_strain=False)
            ranked = np.argsort(np.asarray(loc.ratios), kind="stable")[:2]  # the conjugate pair
            normals = np.asarray(loc.normals)[ranked]
        else:
            theta, ratio = np.zeros((1, MAX_MINIMA)), np.full((1, MAX_MINIMA), np.inf)
            count = np.zeros(1, dtype=np.int64)
            minima_plane_strain(sigma, g.p, g.ce, g.SCREEN_SWEEP, theta, ratio, count)
            k = min(int(count[0]), MAX_MINIMA)
            lowest = np.argsort(ratio[0, :k], kind="stable")[:2]  # the conjugate pair
            normals = np.stack([np.cos(theta[0, lowest]), np.sin(theta[0, lowest])], axis=1)
        n = normals[int(np.argmax(np.abs(normals @ ref)))]
        return n if n @ ref >= 0.0 else -n


def share_crack_paths(groups: list, nodes: np.ndarray,
                      full: list[tuple[np.ndarray, np.ndarray]] | None = None,
                      exchange: Exchange | None = None) -> None:
    """Make the EDE groups of a model share one crack-path registry (crack tracking across regions);
    ``full``: each group's cells seen by this MPI rank, ``exchange``: the ranks' (see :class:`CrackPaths`)."""
    if groups:
        paths = CrackPaths(nodes, groups, full, exchange)
        for g in groups:
            g._paths = paths
