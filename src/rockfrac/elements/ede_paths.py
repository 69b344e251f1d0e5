"""Localization onsets and the crack-path registry (cell adjacency, cut cells, tips) of the EDE groups."""

from __future__ import annotations

import math
from dataclasses import dataclass
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
    adjacency (shared edges; in 3D shared faces) over the global cell
    numbering, the cut state of every cell whatever its group (and, on several MPI ranks, whatever
    its rank), the number of cracks started.

    The cut cells' surfaces (segment and normal) are kept in a table over the global cells, filled
    from the groups that cut them: on one process as they cut them; on several ranks each cut is
    announced by its owner (:meth:`announce`), so that every rank takes the same tracking decisions
    (rockfrac.elements.ede). ``full``: each group's cells on every rank, as (global ids,
    connectivity) in the group's serial order (default: the groups' own cells)."""

    def __init__(self, nodes: np.ndarray, groups: list,
                 full: list[tuple[np.ndarray, np.ndarray]] | None = None, exchange: Exchange | None = None):
        self.nodes = nodes
        self.groups = groups
        self.cracks = 0
        self.exchange: Exchange = exchange if exchange is not None else Alone()
        self.stale = False  # the table must be rebuilt from the groups (after a checkpoint's restore)
        full = full if full is not None else [(g.cell_ids, g.cells) for g in groups]
        if len(full) != len(groups):
            raise ValueError(f"{len(full)} full cell lists for {len(groups)} groups")
        self.full_conn = [np.asarray(c) for _, c in full]  # each group's cells of every rank, serial order
        self.full_ids = [np.asarray(i) for i, _ in full]  # and their mesh cells
        n_cells = int(max((i.max(initial=-1) for i, _ in full), default=-1)) + 1
        self.owner = np.full((n_cells, 2), -1, dtype=np.int64)  # (group, local cell) of each own cell
        self.group_of = np.full(n_cells, -1, dtype=np.int64)  # the group of every EDE cell, any rank's
        self.serial = np.full(n_cells, -1, dtype=np.int64)  # its index in its group's serial order
        for k, (ids, _) in enumerate(full):
            self.group_of[ids], self.serial[ids] = k, np.arange(ids.size)
        for k, g in enumerate(groups):
            self.owner[g.cell_ids, 0], self.owner[g.cell_ids, 1] = k, np.arange(g.cell_ids.size)
        self.cut = np.zeros(n_cells, dtype=bool)  # the table of cut cells (every rank's)
        self.segment = np.full((n_cells, 2, 2), np.nan)  # 2D: their surfaces clipped to the cells [m]
        self.anchor = np.full((n_cells, 3), np.nan)  # 3D: a point of their planes [m]
        self.normal = np.zeros((n_cells, 3))
        self.centres = [g.x.mean(axis=1) for g in groups]  # own cell centroids per group [m]
        self._tips: dict[int, tuple[np.ndarray, np.ndarray] | None] = {}  # tip(), until the table changes
        self.nbr: dict[int, list[tuple[int, tuple[int, ...]]]] = {}  # (neighbour, shared nodes)
        gids = np.concatenate([i for i, _ in full] + [np.zeros(0, dtype=np.int64)])
        if gids.size == 0:
            return
        conn = np.vstack([c for _, c in full if c.size])
        self.cell_nodes = np.full((n_cells, conn.shape[1]), -1, dtype=np.int64)  # every EDE cell's nodes
        self.cell_nodes[gids] = conn
        sides = SIDES.get(conn.shape[1]) if nodes.shape[1] == 3 else None  # 3D: faces; 2D: edges
        if sides is None:
            sides = np.stack([np.arange(conn.shape[1]), np.roll(np.arange(conn.shape[1]), -1)], axis=1)
        pairs = conn[:, sides].reshape(-1, sides.shape[1])
        owner = np.repeat(gids, sides.shape[0])
        key = np.sort(pairs, axis=1)
        order = np.lexsort(key.T[::-1])
        ks = key[order]
        for i in np.flatnonzero(np.all(ks[1:] == ks[:-1], axis=1)):  # once, at set-up
            c1, c2 = int(owner[order[i]]), int(owner[order[i + 1]])
            shared = tuple(int(v) for v in ks[i])
            self.nbr.setdefault(c1, []).append((c2, shared))
            self.nbr.setdefault(c2, []).append((c1, shared))

    def _cell(self, gcell: int):
        g, local = self.owner[gcell]
        return (None, -1) if g < 0 else (self.groups[g], int(local))

    # -- the table of cut cells -------------------------------------------------------------------
    def record(self, gcell: int, surface: np.ndarray, normal: np.ndarray) -> None:
        """Enter a cut cell's surface in the table: its segment (2, 2) in 2D, a point of its plane
        (3,) in 3D [m]."""
        self.cut[gcell] = True
        self._tips.clear()
        if np.shape(surface) == (3,):
            self.anchor[gcell] = surface
        else:
            self.segment[gcell] = surface
        self.normal[gcell] = normal

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

    def sync(self) -> None:
        """Rebuild the table from every rank's groups (a collective call)."""
        mine = []
        for g in self.groups:
            loc = np.flatnonzero(g.e_state[:, K.E_LOC] == 1.0)
            mine.append((g.cell_ids[loc], self._surface(g, loc), g.e_state[loc, K.E_N:K.E_N + 3]))
        self.cut[:] = False
        self._tips.clear()
        self.segment[:] = np.nan
        self.anchor[:] = np.nan
        self.normal[:] = 0.0
        for part in self.exchange.allgather(mine):
            for ids, surface, normal in part:
                self.cut[ids], self.normal[ids] = True, normal
                if surface.ndim == 2 and surface.shape[1] == 3:
                    self.anchor[ids] = surface
                else:
                    self.segment[ids] = surface
        self.stale = False

    def current(self) -> None:
        """The table brought up to date where it is stale (every rank restored a checkpoint)."""
        if self.stale:
            self.sync()

    # -- tracking -----------------------------------------------------------------------------------
    def is_cut(self, gcell: int) -> bool:
        return bool(self.cut[gcell])

    def cut_neighbours(self, gcell: int) -> list[int]:
        return [c for c, _ in self.nbr.get(gcell, []) if self.cut[c]]

    def tip(self, gcell: int) -> tuple[np.ndarray, np.ndarray] | None:
        """(point, neighbour normal) where a cut neighbour's surface ends on the side shared with
        gcell: in 2D the end of its segment on the shared edge; in 3D the middle of the edge its
        polygon leaves on the shared face (the crack front there). Memoized until the table changes."""
        if gcell not in self._tips:
            self._tips[gcell] = self._tip(gcell)
        found = self._tips[gcell]
        return None if found is None else (found[0].copy(), found[1].copy())

    def _tip(self, gcell: int) -> tuple[np.ndarray, np.ndarray] | None:
        if self.nodes.shape[1] == 3:
            return self._tip_3d(gcell)
        for c, (a, b) in self.nbr.get(gcell, []):
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

    def _tip_3d(self, gcell: int) -> tuple[np.ndarray, np.ndarray] | None:
        for c, face in self.nbr.get(gcell, []):
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

    def tip_cells_global(self, k: int) -> set[int]:
        """Global ids of the uncut cells of group k (on any rank) at a crack tip."""
        out = set()
        for gcell in np.flatnonzero(self.cut).tolist():
            for c, _ in self.nbr.get(gcell, []):
                if self.group_of[c] == k and not self.cut[c] and c not in out and self.tip(c) is not None:
                    out.add(c)
        return out

    def tip_cells(self, group) -> set[int]:
        """Local indices in ``group`` of its uncut cells at a crack tip."""
        k = self.groups.index(group)
        return {int(self.owner[c, 1]) for c in self.tip_cells_global(k) if self.owner[c, 0] == k}

    def nonlocal_stress(self, point: np.ndarray, length: float) -> np.ndarray:
        """The nonlocal stress (6,) [Pa] at ``point`` (a crack tip): the average of the uncut cells'
        stresses with the Gaussian weight exp(-r^2 / (2 length^2)) of their centroids' distance r to
        the point (Wells & Sluys 2001), cut off at 3 length; NaN if no uncut cell is that close. On
        several MPI ranks, a collective call: the sums over every rank's cells."""
        x = np.asarray(point, dtype=float)[:self.nodes.shape[1]]
        total, weight = np.zeros(6), 0.0
        for g, centre in zip(self.groups, self.centres):
            r2 = ((centre - x) ** 2).sum(axis=1)
            near = np.flatnonzero((r2 <= 9.0 * length**2) & (g.e_state[:, K.E_LOC] == 0.0))
            w = np.exp(-r2[near] / (2.0 * length**2))
            total += np.einsum("e,eq,eqi->i", w, g.wdet[near], g.sigma[near])
            weight += float(w @ g.wdet[near].sum(axis=1))
        parts = self.exchange.allgather((total, weight))  # every rank's cells (one process: its own)
        total, weight = parts[0]
        for t, w_r in parts[1:]:
            total, weight = total + t, weight + w_r
        return total / weight if weight > 0.0 else np.full(6, np.nan)

    def nonlocal_normal(self, gcell: int, point: np.ndarray, reference: np.ndarray, length: float) -> np.ndarray:
        """Normal (2,) in 2D, (3,) in 3D, that continues a crack from ``point`` (its tip, on the
        boundary of cell gcell): of the conjugate bifurcation normals (eq. 7-8) of the nonlocal stress
        at the tip (:meth:`nonlocal_stress`; in 3D the two lowest minima of det A(n) / det A^e(n) on
        the unit sphere), the one closest to ``reference`` (the crack's last normal), signed like it.
        The direction comes from the stress the crack grows into, not from the singular field of the
        one cell at its tip. The tip cell's law gives the tangent."""
        g = self.groups[self.group_of[gcell]]  # its law (the cell may be another rank's)
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


def share_crack_paths(groups: list, nodes: np.ndarray, full: list[tuple[np.ndarray, np.ndarray]] | None = None,
                      exchange: Exchange | None = None) -> None:
    """Make the EDE groups of a model share one crack-path registry (crack tracking across regions);
    ``full``: each group's cells on every MPI rank, ``exchange``: the ranks' (see :class:`CrackPaths`)."""
    if groups:
        paths = CrackPaths(nodes, groups, full, exchange)
        for g in groups:
            g._paths = paths
