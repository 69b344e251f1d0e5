"""Cracks present from the start in the EDE continuum: the cells a polyline (2D) or a plane (3D) crosses are
cut at t = 0.

A joint or fault given as a polyline: every cell of an EDE group that it crosses is localized before
the first step, with the chord of the polyline through the cell as its surface (normal, + side and
active nodes as :meth:`EmbeddedDruckerPrager.localize_cell`) and the given peak cohesion. A straight
crack gives every cell the same line, so its cells' + sides agree and a uniform jump is exactly a
rigid sliding of the two sides (no stress locking). The crack's ends inside the body are crack tips
for tracking, and it counts toward ``max_cracks``.

A node on the crack would be on neither side: the cells that only touch the crack at that node
would stay uncut and tie the two sides together there (the crack locks). A polyline segment that
passes within NODE_TOL cell sizes of a node is therefore moved off the nodes by twice that along
its normal, so that every such node is on one side and the cells around it are cut, some by a
sliver.
"""

from __future__ import annotations

import numpy as np

from rockfrac.elements.ede_paths import CrackPaths, Exchange

LENGTH_TOL = 1e-9  # relative: chords shorter than this x the cell size are not cuts
NODE_TOL = 1e-7  # relative: a segment this close to a node (x the cell size) is moved off it


def clip_to_cell(xe: np.ndarray, a: np.ndarray, b: np.ndarray) -> tuple[float, float] | None:
    """Parameters (s0, s1) in [0, 1] of the part of segment a-b inside the convex cell xe (k, 2),
    or None (Cyrus-Beck)."""
    d = b - a
    s0, s1 = 0.0, 1.0
    k = xe.shape[0]
    area2 = sum(xe[i, 0] * xe[(i + 1) % k, 1] - xe[(i + 1) % k, 0] * xe[i, 1] for i in range(k))
    turn = 1.0 if area2 > 0.0 else -1.0  # counter-clockwise: the inside is to the left of each edge
    for i in range(k):
        p, q = xe[i], xe[(i + 1) % k]
        edge = q - p
        inward = turn * np.array([-edge[1], edge[0]])
        num = float(inward @ (a - p))
        den = float(inward @ d)
        if abs(den) < 1e-300:
            if num < 0.0:
                return None
            continue
        s = -num / den
        if den > 0.0:
            s0 = max(s0, s)
        else:
            s1 = min(s1, s)
        if s0 >= s1:
            return None
    return s0, s1


def _off_the_nodes(a: np.ndarray, b: np.ndarray, groups: list[tuple[np.ndarray, np.ndarray]],
                   exchange: Exchange) -> tuple[np.ndarray, np.ndarray]:
    """The segment a-b, moved off the nodes (module doc) if it passes within NODE_TOL cell sizes of
    a node of any group's cells ((corners (n_el, k, 2), sizes (n_el,)) per group; this MPI rank's,
    the test made over every rank's: a collective call): every group then cuts its cells with the
    same line, so that the crack's traces on the sides between two regions agree and its pieces
    join there."""
    length = float(np.linalg.norm(b - a))
    t, n = (b - a) / length, np.array([a[1] - b[1], b[0] - a[0]]) / length
    close, smallest = False, np.inf
    for xe, size in groups:
        side, along = (xe - a) @ n, (xe - a) @ t
        span = (along.max(axis=1) >= 0.0) & (along.min(axis=1) <= length)
        if span.any():
            close |= bool(np.min(np.abs(side[span]) / size[span, None]) < NODE_TOL)
            smallest = min(smallest, float(size[span].min()))
    every = exchange.allgather((close, smallest))
    if not any(c for c, _ in every):
        return a, b
    shift = 2.0 * NODE_TOL * min(size for _, size in every)
    return a + shift * n, b + shift * n


def cut_along(paths: CrackPaths, points: np.ndarray, c_p: float) -> tuple[int, float]:
    """Localize every EDE cell the polyline ``points`` (n, 2) [m] crosses (module doc); returns the
    number of cells cut and the fraction of the polyline's length that lies in EDE cells.

    On several MPI ranks (a collective call) each rank cuts its own cells; the cuts are announced
    on every rank (:meth:`EmbeddedDruckerPrager.cut_announced`) and counted in the serial run's
    order (group, first polyline segment, cell), and the crack-path table is filled from every
    rank's."""
    pts = np.asarray(points, dtype=float)
    total = float(np.sum(np.linalg.norm(np.diff(pts, axis=0), axis=1)))
    cells = [(g.x[..., :2], np.sqrt(g.wdet.sum(axis=1))) for g in paths.groups]  # this rank's, per group
    segments = [_off_the_nodes(a, b, cells, paths.exchange) for a, b in zip(pts[:-1], pts[1:])]
    mine = []  # this rank's cuts: (group, first segment, serial index, whole mesh id, length in the cell)
    for k, (g, (xe, size)) in enumerate(zip(paths.groups, cells)):
        chords: dict[int, tuple[int, list[np.ndarray]]] = {}
        for j, (a, b) in enumerate(segments):
            length = float(np.linalg.norm(b - a))
            t, n = (b - a) / length, np.array([a[1] - b[1], b[0] - a[0]]) / length
            side, along = (xe - a) @ n, (xe - a) @ t  # (n_el, k): across and along the segment
            span = (along.max(axis=1) >= 0.0) & (along.min(axis=1) <= length)
            near = np.flatnonzero((side.min(axis=1) <= 0.0) & (side.max(axis=1) >= 0.0) & span)
            for cell in near.tolist():  # the cells the segment's line crosses within its length only
                s = clip_to_cell(xe[cell], a, b)
                if s is None or (s[1] - s[0]) * np.linalg.norm(b - a) <= LENGTH_TOL * size[cell]:
                    continue
                chord = np.array([a + s[0] * (b - a), a + s[1] * (b - a), a, b])
                chords.setdefault(cell, (j, []))[1].append(chord)
        for e, (j, pieces) in chords.items():
            if len(pieces) == 1:  # the line of its polyline segment, through the segment's start: every
                start, end = pieces[0][2], pieces[0][3]  # cell computes the same side for a node on it
            else:  # a polyline vertex inside the cell: the chord across it
                start, end = pieces[0][0], pieces[-1][1]
            d = end - start
            normal = np.array([-d[1], d[0]]) / np.linalg.norm(d)
            side = (xe[e] - start) @ normal
            if not (side.min() < -LENGTH_TOL * size[e] and side.max() > LENGTH_TOL * size[e]):
                continue  # along an edge of the cell, or through a corner only: not a cut of this cell
            g.localize_cell(e, normal, c_p=c_p, point=start)
            mine.append((k, j, int(g.serial_index[e]), int(g.whole_ids[e]),
                         sum(float(np.linalg.norm(piece[1] - piece[0])) for piece in pieces)))
    covered = 0.0
    every = sorted((c for part in paths.exchange.allgather(mine) for c in part), key=lambda c: c[:3])
    for k, _, _, gcell, inside in every:
        paths.groups[k].cut_announced(gcell)
        covered += inside
    paths.cracks += 1
    paths.sync()
    return len(every), covered / total


def cut_by_plane(groups: list, point: np.ndarray, normal: np.ndarray, c_p: float) -> int:
    """A general 3D body: localize every cell of the EDE groups that the plane through ``point`` [m]
    with ``normal`` crosses (nodes on both sides), the plane itself as their surface; returns the
    number of cells cut (summed over the MPI ranks; a collective call).

    One plane for every cell: their + sides agree and a uniform jump is a rigid sliding of the two
    sides. A plane within NODE_TOL cell sizes of a node is first moved off the nodes by twice that
    along its normal (the same shift on every rank), as a 2D crack is (module doc)."""
    n = np.asarray(normal, dtype=float) / np.linalg.norm(normal)
    p0 = np.asarray(point, dtype=float)
    exchange = groups[0].paths.exchange
    near = []  # per group of this rank: (the nodes' least distance to the plane / cell size, least size)
    for g in groups:
        d = (g.x - p0) @ n  # (n_el, m)
        size = np.cbrt(g.wdet.sum(axis=1))
        crossed = (d.min(axis=1) <= 0.0) & (d.max(axis=1) >= 0.0)
        if crossed.any():
            near.append((float((np.abs(d[crossed]) / size[crossed, None]).min()), float(size[crossed].min())))
    near = [pair for part in exchange.allgather(near) for pair in part]
    if near and min(gap for gap, _ in near) < NODE_TOL:
        p0 = p0 + 2.0 * NODE_TOL * min(size for _, size in near) * n
    cut = 0
    for g in groups:  # each rank cuts its own cells; all announce every cut, in the serial order
        d = (g.x - p0) @ n
        crossed = np.flatnonzero((d.max(axis=1) > 0.0) & (d.min(axis=1) <= 0.0))
        for e in crossed.tolist():
            g.localize_cell(e, n, c_p=c_p, point=p0)
        cut += crossed.size
        mine = [(int(g.serial_index[e]), int(g.whole_ids[e])) for e in crossed.tolist()]
        for _, gcell in sorted(c for part in exchange.allgather(mine) for c in part):
            g.cut_announced(gcell)
    return int(sum(exchange.allgather(cut)))
