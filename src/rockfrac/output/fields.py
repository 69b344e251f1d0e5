"""The fields of a converged step for ParaView: displacement, cell-averaged stresses and plastic
variables, cohesive surfaces (zero-thickness quads) and embedded crack segments (2D) or polygons (3D, as
triangles) with their jumps,
tractions, strengths and states (see :mod:`rockfrac.output.vtk` for how each is written)."""

from __future__ import annotations

import numpy as np

from rockfrac.fem.planes import MAX_VERTICES, fan_triangles
from rockfrac.laws.cohesive_params import MODE_PLASTIC
from rockfrac.output.vtk import CellKind, CrackState, StepFields, step_fields


def _bulk_fields(built, u: np.ndarray, cells: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """Per-cell fields over all bulk groups: stress (6), plastic strain (6), gamma, localized, region;
    of every cell of a serial model, or of an MPI rank's own ``cells`` (sorted, for its piece)."""
    n_el = built.mesh.cells.shape[0] if cells is None else cells.shape[0]
    out = {"stress": np.zeros((n_el, 6)), "plastic_strain": np.zeros((n_el, 6)), "gamma": np.zeros(n_el),
           "localized": np.zeros(n_el, dtype=np.int8), "region": np.zeros(n_el, dtype=np.int32)}
    for k, g in enumerate(built.bulks):
        rows = g.cell_ids if cells is None else np.searchsorted(cells, g.cell_ids)
        out["region"][rows] = k
        for name, values in g.cell_fields(u).items():
            out[name][rows] = values
    return out


def _pair_index(minus: np.ndarray, plus: np.ndarray, n: int, qm: np.ndarray, qp: np.ndarray):
    """Index of each query pair (qm, qp) among the pairs (minus, plus), and whether it is there."""
    keys = minus * n + plus
    if keys.size == 0:
        return np.zeros(qm.size, dtype=np.int64), np.zeros(qm.size, dtype=bool)
    order = np.argsort(keys)
    q = qm * n + qp
    pos = np.clip(np.searchsorted(keys[order], q), 0, keys.size - 1)
    return order[pos], keys[order][pos] == q


def _interface_fields(built, u: np.ndarray, on_ranks: bool = False) -> dict[str, np.ndarray]:
    """Per interface cell: the mean of its node-pair points (jump, traction, strengths, state), the
    vectors in the local frame ((t, n) in 2D, (t1, t2, n) in 3D); of a serial model, or (on_ranks)
    of an MPI rank's own interface cells of its piece, each rank's sums over its points sent
    to the cells' owners (the others' entries left empty)."""
    mesh = built.mesh
    cells, n = mesh.interfaces, mesh.n_nodes
    n_if, half = cells.shape[0], cells.shape[1] // 2
    comps = ("t", "n") if mesh.dim == 2 else ("t1", "t2", "n")  # the local frame
    d = len(comps)
    sums = {"jump": np.zeros((n_if, d)), "traction": np.zeros((n_if, d)), "plastic_jump": np.zeros((n_if, d))}
    written = {name: np.zeros(n_if, dtype=np.int8) for g in built.cohesives for name in g.law.record_names}
    for name in written:
        sums[name] = np.zeros(n_if)
    count = np.zeros(n_if)
    state = np.full(n_if, -1, dtype=np.int8)
    for g in built.cohesives:
        rec = g.records(u)
        vals = {"jump": np.column_stack([rec[f"jump_{c}"] for c in comps]),
                "traction": np.column_stack([rec[f"T_{c}"] for c in comps]),
                "plastic_jump": np.column_stack([rec[f"jump_p_{c}"] for c in comps])}
        vals.update({name: rec[name] for name in g.law.record_names})
        rigid = g.rigid
        st = np.where(rec["mode"] == MODE_PLASTIC, CrackState.PLASTIC,
                      CrackState.CONSTRAINED if rigid else CrackState.ELASTIC).astype(np.int8)
        for a, b in ((j, half + j) for j in range(half)):  # the node pairs of each interface cell
            idx, hit = _pair_index(g.points.minus, g.points.plus, n, cells[:, a], cells[:, b])
            for name, v in vals.items():
                if name in g.law.record_names:
                    written[name][hit] = 1
                sums[name][hit] += v[idx[hit]]
            count[hit] += 1
            state[hit] = np.maximum(state[hit], st[idx[hit]])
    if on_ranks:
        sums, count, state, written = _to_owners(built, sums, count, state, written)
    for name, w in written.items():  # NaN where the cell's law has no such quantity
        sums[name][w == 0] = np.nan
    with np.errstate(invalid="ignore", divide="ignore"):
        out = {name: (v.T / count).T for name, v in sums.items()}  # NaN where no point (a crack tip pair)
    out["state"] = state
    return out


def _to_owners(built, sums: dict[str, np.ndarray], count: np.ndarray, state: np.ndarray,
               written: dict[str, np.ndarray]) -> tuple[dict, np.ndarray, np.ndarray, dict]:
    """This rank's sums over its points, per interface cell, sent to the ranks owning the cells and
    added there: each rank ends with its own cells' sums over every rank's points (the partition's
    surface is all that travels)."""
    owner, rank = built.partition.interface_part, built.model.rank
    whole = built.mesh.place.interfaces if built.mesh.place is not None else np.arange(owner.shape[0])
    touched = np.flatnonzero((count > 0) & (owner != rank))
    parts: list = []
    for r in range(built.partition.n_parts):  # each cell named by its index in the whole mesh
        ids = touched[owner[touched] == r]
        parts.append((whole[ids], {k: v[ids] for k, v in sums.items()}, count[ids], state[ids],
                      {k: w[ids] for k, w in written.items()}) if ids.size else None)
    others = [None if got is None else (np.searchsorted(whole, got[0]),) + got[1:]
              for got in built.model.exchange(parts)]
    mine = owner == rank
    for v in (*sums.values(), count, *written.values()):  # this rank's own cells' sums stay
        v[~mine] = 0
    state[~mine] = -1
    for got in others:
        if got is None:
            continue
        ids, s, c, st, w = got
        assert mine[ids].all()
        for k, v in s.items():
            sums[k][ids] += v
        count[ids] += c
        np.maximum.at(state, ids, st)
        for k, v in w.items():
            np.maximum.at(written[k], ids, v)
    return sums, count, state, written


def _segments(built) -> tuple[tuple[np.ndarray, np.ndarray] | None, np.ndarray | None, dict]:
    """End points of the embedded crack segments, their host cells and fields: in 2D the surface
    clipped to its cell; for a hexahedron of a plane-strain slab cut normal to z, the surface's trace
    on the cell's z face (a general 3D surface has no segment: not drawn). Each group's segments of
    every MPI rank, in the group's serial order."""
    parts = []
    for g in built.embeddeds:
        cells = g.localized()
        lines = g.segments if g.dim == 2 else g.sections
        drawn = np.isfinite(lines[cells]).all(axis=(1, 2))
        rec = {k: v[drawn] for k, v in g.records().items()}
        cells = cells[drawn]
        seg = lines[cells]
        mine = {"x0": seg[:, 0], "x1": seg[:, 1], "host": g.whole_ids[cells],
                "jump": np.column_stack([rec["jump_t"], rec["jump_n"]]),
                "traction": np.column_stack([rec["T_t"], rec["T_n"]]), "c": rec["c"], "tan_phi": rec["tan_phi"],
                "state": np.where(rec["mode"] == 1.0, CrackState.PLASTIC, CrackState.CONSTRAINED).astype(np.int8)}
        whole = built.model.gather_records(mine, g.serial_index[cells])
        if whole is not None and whole["host"].size:
            parts.append(whole)
    if not parts:
        return None, None, {}
    x0, x1 = np.vstack([p["x0"] for p in parts]), np.vstack([p["x1"] for p in parts])
    names = ("jump", "traction", "c", "tan_phi", "state")
    return (x0, x1), np.concatenate([p["host"] for p in parts]), {k: np.concatenate([p[k] for p in parts])
                                                                  for k in names}


def _surfaces(built, disp) -> tuple[np.ndarray | None, np.ndarray | None, dict, dict]:
    """A general 3D body's embedded crack surfaces: each cut cell's polygon as a fan of triangles
    (vertices (k, 3, 3) [m]), their host cells, their fields (jump and traction in the surface's frame
    (t, n x t, n), strengths, state) and the displacement at their vertices (3k, 3), exact: each vertex
    is on a cell edge, along which the nodal field is linear. Every MPI rank's, in the serial order.
    disp(nodes): the displacement (k, 3) at mesh nodes (of this rank's cells)."""
    parts = []
    for g in built.embeddeds:
        if g.dim != 3 or g.plane_strain:
            continue
        cells = g.localized()
        verts, ends, where = g.surface_polygons(cells)
        poly, tri = fan_triangles(verts)
        corners = tri.ravel()
        a = g.cells[cells[poly].repeat(3), ends.reshape(-1, 2)[corners, 0]]
        b = g.cells[cells[poly].repeat(3), ends.reshape(-1, 2)[corners, 1]]
        w = where.ravel()[corners][:, None]
        rec = g.records()  # the localized cells' in order, with the (t, n x t, n) components
        mine = {"x": verts.reshape(-1, 3)[tri], "u": ((1.0 - w) * disp(a) + w * disp(b)).reshape(-1, 3, 3),
                "host": g.whole_ids[cells][poly],
                "jump": np.column_stack([rec["jump_t1"], rec["jump_t2"], rec["jump_n"]])[poly],
                "traction": np.column_stack([rec["T_t1"], rec["T_t2"], rec["T_n"]])[poly],
                "c": rec["c"][poly], "tan_phi": rec["tan_phi"][poly],
                "state": np.where(rec["mode"] == 1.0, CrackState.PLASTIC, CrackState.CONSTRAINED).astype(np.int8)[poly]}
        order = g.serial_index[cells][poly] * (4 * MAX_VERTICES) + np.arange(poly.size) - np.searchsorted(poly, poly)
        whole = built.model.gather_records(mine, order)
        if whole is not None and whole["host"].size:
            parts.append(whole)
    if not parts:
        return None, None, {}, {}
    names = ("jump", "traction", "c", "tan_phi", "state")
    return (np.vstack([p["x"] for p in parts]), np.concatenate([p["host"] for p in parts]),
            {k: np.concatenate([p[k] for p in parts]) for k in names},
            {"displacement": np.vstack([p["u"] for p in parts]).reshape(-1, 3)})


def step_piece(built, u: np.ndarray) -> StepFields:
    """This MPI rank's piece of the step's fields (a collective call): its own bulk cells, interface
    cells and embedded segments or triangles, on the nodes they use, with the fields ``node_id`` and
    ``cell_id`` pointing into the whole model's grid (the serial run's), as
    :func:`rockfrac.output.vtk.piece_of` names them; every piece has every field of that grid.

    Built from the rank's own cells, nothing of the whole mesh's size: the displacement is scattered
    to the piece's nodes only (an interface cell's nodes need not be the rank's dofs), the bulk
    fields are the rank's cells', and each interface cell's sums over its points come from the
    ranks holding them to the cell's owner. The embedded segments and triangles of every rank are
    gathered (the cracked cells only), to number them in the serial order."""
    mesh, model = built.mesh, built.model
    part, rank = built.partition, model.rank
    place = mesh.place  # where the rank's piece of the mesh sits in the whole
    assert place is not None
    own = np.flatnonzero(part.cell_part == rank)
    own_if = np.flatnonzero(part.interface_part == rank)
    interfaces = mesh.interfaces[own_if]
    nodes = np.unique(np.concatenate([mesh.cells[own].ravel(), interfaces.ravel()]))
    disp = model.values_at(u, (mesh.dim * nodes[:, None] + np.arange(mesh.dim)).ravel()).reshape(-1, mesh.dim)

    def row(a: np.ndarray) -> np.ndarray:  # a mesh node's row in the piece
        return np.searchsorted(nodes, a)

    segments, seg_hosts, seg_data = _segments(built)  # hosts by their whole mesh ids
    triangles, tri_hosts, tri_data, tri_points = _surfaces(built, lambda a: disp[row(a)])
    mine = place.cells[own]  # the whole mesh's ids of the rank's own cells
    seg = np.flatnonzero(np.isin(seg_hosts, mine)) if seg_hosts is not None else np.zeros(0, np.int64)
    tri = np.flatnonzero(np.isin(tri_hosts, mine)) if tri_hosts is not None else np.zeros(0, np.int64)
    bulk = _bulk_fields(built, u, own)
    inter = ({name: v[own_if] for name, v in _interface_fields(built, u, on_ranks=True).items()}
             if place.n_interfaces else None)  # alike on every rank (a collective call)
    corners = (3 * tri[:, None] + np.arange(3)).ravel()
    piece = step_fields(
        mesh.nodes[nodes], row(mesh.cells[own]), mesh.cell_type,
        interfaces=row(interfaces) if own_if.size else None,
        segments=(segments[0][seg], segments[1][seg]) if segments is not None and seg.size else None,
        segment_cells=np.searchsorted(mine, seg_hosts[seg]) if seg_hosts is not None else None,
        point_data={"displacement": disp}, bulk_data=bulk, interface_data=inter,
        segment_data={k: v[seg] for k, v in seg_data.items()} or None,
        triangles=triangles[tri] if triangles is not None and tri.size else None,
        triangle_data={k: v[tri] for k, v in tri_data.items()} or None,
        triangle_point_data={k: v[corners] for k, v in tri_points.items()} or None)
    n_seg = 0 if seg_hosts is None else seg_hosts.shape[0]
    node_id = np.concatenate([place.nodes[nodes], place.n_nodes + (2 * seg[:, None] + np.arange(2)).ravel(),
                              place.n_nodes + 2 * n_seg + corners]).astype(np.int64)
    ids = {CellKind.BULK: place.cells[own], CellKind.INTERFACE: place.interfaces[own_if], "line": seg, "triangle": tri}
    kinds: list = []  # each block's kind; embedded cells are segments ("line") or triangles
    for (meshio_type, _), k in zip(piece.cells, piece.cell_data["cell_kind"]):
        kind = CellKind(int(k[0])) if k.size else CellKind.BULK  # only the bulk block may be empty
        kinds.append(kind if kind is not CellKind.EMBEDDED else "line" if meshio_type == "line" else "triangle")
    whole = {CellKind.BULK: bulk, CellKind.INTERFACE: inter or {}, "line": seg_data, "triangle": tri_data}
    present = [CellKind.BULK] + ([CellKind.INTERFACE] if place.n_interfaces else []) + \
        (["line"] if n_seg else []) + (["triangle"] if tri_hosts is not None and tri_hosts.size else [])
    return _as_in_the_whole_grid(piece, kinds, [ids[k] for k in kinds], node_id,
                                 [whole[k] for k in present])


def _as_in_the_whole_grid(piece: StepFields, kinds: list, cell_ids: list[np.ndarray], node_id: np.ndarray,
                          whole_kinds: list[dict[str, np.ndarray]]) -> StepFields:
    """The piece with the fields and dtypes of the whole grid, whose blocks' fields are
    ``whole_kinds`` (one dict per kind of cell the whole grid has): a field some kind lacks is NaN
    there and float64 in every piece; empty blocks dropped; node_id and cell_id added."""
    tails = {name: np.asarray(v).shape[1:] for fields in whole_kinds for name, v in fields.items()}
    complete = {name for name in tails if all(name in fields for fields in whole_kinds)}
    keep = [b for b, (_, conn) in enumerate(piece.cells) if conn.shape[0]]
    cells = [piece.cells[b] for b in keep]
    data: dict[str, list[np.ndarray]] = {}
    for name in list(tails) + ["cell_kind"]:
        blocks = []
        for b in keep:
            have = piece.cell_data.get(name)
            arr = have[b] if have is not None else np.full((piece.cells[b][1].shape[0], *tails[name]), np.nan)
            blocks.append(arr if name in complete or name == "cell_kind" else np.asarray(arr, dtype=np.float64))
        data[name] = blocks
    data["cell_id"] = [np.asarray(cell_ids[b], dtype=np.int64) for b in keep]
    point_data = dict(piece.point_data, node_id=node_id)
    return StepFields(piece.points, cells, point_data, data)


def step_output(built, u: np.ndarray) -> StepFields:
    """The ParaView fields of a serial model's committed state at displacement u (an MPI run's
    ranks make pieces, :func:`step_piece`, which :func:`rockfrac.output.vtk.join_pieces` joins)."""
    mesh = built.mesh
    disp = u[: mesh.dim * mesh.n_nodes].reshape(-1, mesh.dim)
    segments, hosts, seg_data = _segments(built)
    triangles, _, tri_data, tri_points = _surfaces(built, lambda a: disp[a])
    return step_fields(
        mesh.nodes, mesh.cells, mesh.cell_type,
        interfaces=mesh.interfaces if mesh.interfaces.size else None,
        segments=segments, segment_cells=hosts,
        point_data={"displacement": disp},
        bulk_data=_bulk_fields(built, u),
        interface_data=_interface_fields(built, u) if mesh.interfaces.size else None,
        segment_data=seg_data or None,
        triangles=triangles, triangle_data=tri_data or None,
        triangle_point_data=tri_points or None,
    )
