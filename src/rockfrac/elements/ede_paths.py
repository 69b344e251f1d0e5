"""Localization onsets and the crack-path registry (cell adjacency, cut cells, tips) of the EDE groups."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rockfrac.elements import ede_kernel as K
from rockfrac.laws.bifurcation_plane import MAX_MINIMA, minima_plane_strain


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
        self.centres = [g.x[..., :2].mean(axis=1) for g in groups]  # cell centroids per group [m]
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

    def nonlocal_stress(self, point: np.ndarray, length: float) -> np.ndarray:
        """The nonlocal stress (6,) [Pa] at ``point`` (a crack tip): the average of the uncut cells'
        stresses with the Gaussian weight exp(-r^2 / (2 length^2)) of their centroids' distance r to
        the point (Wells & Sluys 2001), cut off at 3 length; NaN if no uncut cell is that close."""
        x = np.asarray(point, dtype=float)[:2]
        total, weight = np.zeros(6), 0.0
        for g, centre in zip(self.groups, self.centres):
            r2 = ((centre - x) ** 2).sum(axis=1)
            near = np.flatnonzero((r2 <= 9.0 * length**2) & (g.e_state[:, K.E_LOC] == 0.0))
            w = np.exp(-r2[near] / (2.0 * length**2))
            total += np.einsum("e,eq,eqi->i", w, g.wdet[near], g.sigma[near])
            weight += float(w @ g.wdet[near].sum(axis=1))
        return total / weight if weight > 0.0 else np.full(6, np.nan)

    def nonlocal_normal(self, gcell: int, point: np.ndarray, reference: np.ndarray, length: float) -> np.ndarray:
        """Normal (2,) that continues a crack from ``point`` (its tip, on the boundary of cell gcell):
        of the conjugate bifurcation normals (eq. 7-8) of the nonlocal stress at the tip
        (:meth:`nonlocal_stress`), the one closest to ``reference`` (the crack's last normal), signed
        like it. The direction comes from the stress the crack grows into, not from the singular
        field of the one cell at its tip. The tip cell's law gives the tangent."""
        g, _ = self._cell(gcell)
        ref = np.asarray(reference, dtype=float)[:2]
        sigma = self.nonlocal_stress(point, length)[None, :]
        if not np.all(np.isfinite(sigma)):
            return ref / np.linalg.norm(ref)
        theta, ratio = np.zeros((1, MAX_MINIMA)), np.full((1, MAX_MINIMA), np.inf)
        count = np.zeros(1, dtype=np.int64)
        minima_plane_strain(sigma, g.p, g.ce, g.SCREEN_SWEEP, theta, ratio, count)
        k = min(int(count[0]), MAX_MINIMA)
        lowest = np.argsort(ratio[0, :k], kind="stable")[:2]  # the conjugate pair
        normals = np.stack([np.cos(theta[0, lowest]), np.sin(theta[0, lowest])], axis=1)
        n = normals[int(np.argmax(np.abs(normals @ ref)))]
        return n if n @ ref >= 0.0 else -n


def share_crack_paths(groups: list, nodes: np.ndarray) -> None:
    """Make the EDE groups of a model share one crack-path registry (crack tracking across regions)."""
    if groups:
        paths = CrackPaths(nodes, groups)
        for g in groups:
            g._paths = paths
