"""ParaView output: one VTU file per converged step and a ``.pvd`` collection that lists them.

Plain arrays in, files out; nothing here knows the engine. A step is one unstructured grid that
holds three kinds of cells (the cell field ``cell_kind`` tells them apart, see `CellKind`):

- bulk cells: "triangle", "quad", "tetra" or "hexahedron" (rockfrac's tri3, quad4, tet4, hex8; VTK order);
- cohesive interfaces (m0, m1, p0, p1) as "quad" cells (m0, m1, p1, p0) (in 3D the minus face and
  the plus face as one "wedge" (triangles) or "hexahedron" (quadrilaterals)). They have zero area in
  the reference configuration and open with ParaView's "Warp By Vector": the minus nodes move
  with the minus side and the plus nodes with the plus side. Opened, the quad is counter-
  clockwise, since (t, n) is right-handed. (A "line" (m0, m1) would hide the opening.) In 2D
  ParaView shows them together with the bulk quads; use "Threshold" on ``cell_kind`` to split them.
- embedded EDE cracks as "line" cells between EXTRA points appended after the mesh nodes, two
  per segment (`crack_segments_from_points`). A nodal field at these points is its continuous
  interpolation N d in the host cell (`interpolate_nodal`), which is what ParaView draws for the
  bulk cell there. So the warped segment stays on the warped host cell's edges. It is not
  u^- = N d - [[u]] f_S or u^+ = u^- + [[u]]; the jump itself is the line cells' ``jump`` field.

Field conventions (SI units; names are free, these are the ones rockfrac writes):

- points (n, 3): reference coordinates; 2D padded with z = 0. Point fields with 2 columns on a
  2D mesh (displacement) are padded to 3 columns, which "Warp By Vector" needs.
- bulk cells: ``stress`` (n_el, 6), Voigt (xx, yy, zz, xy, yz, xz) averaged over the Gauss
  points, which is ParaView's order for a symmetric tensor. ``plastic_strain`` (n_el, 6) is
  Voigt too, with engineering shears, so ParaView's tensor view shows twice the shear
  components. Also ``gamma`` (accumulated plastic multiplier) and ``localized`` (0/1).
- crack cells (interfaces and embedded lines), averaged over the cell's points: ``jump`` and
  ``traction`` (n, 2) in the local frame (t, n), with T_n > 0 in tension; ``state``
  (a `CrackState` code); ``c``, ``tan_phi``, ...
- a field missing from a block is NaN there (`pad_cell_data`): VTU needs every cell field on
  every cell.

Example::

    series = VtkSeries("out/vtk")
    fields = step_fields(mesh.nodes, mesh.cells, "quad4", interfaces=mesh.interfaces,
                         point_data={"displacement": u.reshape(-1, 2)},
                         bulk_data={"stress": stress}, interface_data={"jump": jump})
    series.write(step, time, fields)  # writes out/vtk/results_00007.vtu, updates results.pvd
"""

from __future__ import annotations

import enum
import os
import re
import xml.etree.ElementTree as ET
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from xml.sax.saxutils import quoteattr

import meshio
import numpy as np

#: rockfrac cell type -> meshio (VTK) cell type; node orders are the same.
MESHIO_TYPES = {"tri3": "triangle", "quad4": "quad", "tet4": "tetra", "hex8": "hexahedron"}


class CellKind(enum.IntEnum):
    """Values of the cell field ``cell_kind``."""

    BULK = 0
    INTERFACE = 1
    EMBEDDED = 2


class CrackState(enum.IntEnum):
    """Codes for the crack cells' ``state`` field (the ``state`` column of points.csv)."""

    CONSTRAINED = 0
    ELASTIC = 1
    PLASTIC = 2


@dataclass
class StepFields:
    """What one step writes: a grid of several cell blocks and its point and cell fields.

    points: (n, 3) reference coordinates [m]; (n, 2) is padded with z = 0.
    cells: blocks of (meshio cell type, connectivity (n_block, nodes per cell)).
    point_data: name -> (n,) or (n, c) array.
    cell_data: name -> one array per block, (n_block,) or (n_block, c); `pad_cell_data` builds it.
    """

    points: np.ndarray
    cells: list[tuple[str, np.ndarray]]
    point_data: dict[str, np.ndarray] = field(default_factory=dict)
    cell_data: dict[str, list[np.ndarray]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.points = _pad_columns(np.asarray(self.points, dtype=np.float64), 3)
        if self.points.ndim != 2 or self.points.shape[1] != 3:
            raise ValueError(f"points must be (n, 2) or (n, 3), got shape {self.points.shape}")
        n = self.points.shape[0]
        for kind, conn in self.cells:
            if conn.size and (conn.min() < 0 or conn.max() >= n):
                raise ValueError(f"{kind!r} cells reference points outside 0..{n - 1}")
        for name, arr in self.point_data.items():
            if arr.shape[0] != n:
                raise ValueError(f"point field {name!r} has {arr.shape[0]} rows for {n} points")
        sizes = [conn.shape[0] for _, conn in self.cells]
        for name, blocks in self.cell_data.items():
            rows = [b.shape[0] for b in blocks]
            if rows != sizes:
                raise ValueError(f"cell field {name!r} has blocks of {rows} rows for blocks of "
                                 f"{sizes} cells (use pad_cell_data)")

    def to_meshio(self) -> meshio.Mesh:
        # int32 connectivity halves the file when the points allow it
        itype = np.int32 if self.points.shape[0] < 2**31 else np.int64
        cells = [(kind, np.ascontiguousarray(conn, dtype=itype)) for kind, conn in self.cells]
        return meshio.Mesh(self.points, cells, point_data=self.point_data, cell_data=self.cell_data)


def piece_of(fields: StepFields, keep: Sequence[np.ndarray]) -> StepFields:
    """The part of a step's grid made of the cells ``keep`` (a mask per block): the points they use,
    renumbered, with the point field ``node_id`` (each point's index in the whole grid) and the cell
    field ``cell_id`` (each cell's index in its block of the whole grid). Every field keeps its
    name, dtype and components, so the pieces of one grid fit together in a .pvtu. (The reference of
    the pieces' format: an MPI run builds its pieces from each rank's own cells,
    :func:`rockfrac.output.fields.step_piece`, and the tests compare them with this.)"""
    if len(keep) != len(fields.cells):
        raise ValueError(f"{len(keep)} masks for {len(fields.cells)} blocks")
    chosen = [np.flatnonzero(k) for k in keep]
    used = np.zeros(fields.points.shape[0], dtype=bool)
    for (_, conn), rows in zip(fields.cells, chosen):
        used[conn[rows].ravel()] = True
    node_id = np.flatnonzero(used)
    local = np.full(fields.points.shape[0], -1, dtype=np.int64)
    local[node_id] = np.arange(node_id.size)
    blocks = [b for b, rows in enumerate(chosen) if rows.size]
    cells = [(fields.cells[b][0], local[fields.cells[b][1][chosen[b]]]) for b in blocks]
    cell_data = {name: [arrays[b][chosen[b]] for b in blocks] for name, arrays in fields.cell_data.items()}
    cell_data["cell_id"] = [chosen[b].astype(np.int64) for b in blocks]
    point_data = {name: arr[node_id] for name, arr in fields.point_data.items()}
    point_data["node_id"] = node_id.astype(np.int64)
    return StepFields(fields.points[node_id], cells, point_data, cell_data)


_VTK_TYPES = {"f8": "Float64", "f4": "Float32", "i1": "Int8", "i2": "Int16", "i4": "Int32", "i8": "Int64",
              "u1": "UInt8", "u2": "UInt16", "u4": "UInt32", "u8": "UInt64"}


def join_pieces(pieces: Sequence[StepFields]) -> StepFields:
    """The whole grid of the pieces of a step (the inverse of :func:`piece_of`): each point and
    cell put at its ``node_id`` and ``cell_id``; the blocks by meshio type and ``cell_kind``, in the
    order of the kinds."""
    n = 1 + max(int(p.point_data["node_id"].max(initial=-1)) for p in pieces)
    points = np.zeros((n, 3))
    point_data: dict[str, np.ndarray] = {}
    blocks: dict[tuple[int, str], list[tuple[StepFields, int]]] = {}
    for p in pieces:
        ids = p.point_data["node_id"]
        points[ids] = p.points
        for name, arr in p.point_data.items():
            if name != "node_id":
                point_data.setdefault(name, np.zeros((n, *arr.shape[1:]), dtype=arr.dtype))[ids] = arr
        for b, (kind, _) in enumerate(p.cells):
            blocks.setdefault((int(p.cell_data["cell_kind"][b][0]), kind), []).append((p, b))
    cells: list[tuple[str, np.ndarray]] = []
    cell_data: dict[str, list[np.ndarray]] = {}
    names = [name for name in pieces[0].cell_data if name != "cell_id"]
    for (_, kind), parts in sorted(blocks.items()):
        size = 1 + max(int(p.cell_data["cell_id"][b].max()) for p, b in parts)
        width = parts[0][0].cells[parts[0][1]][1].shape[1]
        conn = np.zeros((size, width), dtype=np.int64)
        data = {name: np.zeros((size, *parts[0][0].cell_data[name][parts[0][1]].shape[1:]),
                               dtype=parts[0][0].cell_data[name][parts[0][1]].dtype) for name in names}
        for p, b in parts:
            at = p.cell_data["cell_id"][b]
            conn[at] = p.point_data["node_id"][p.cells[b][1]]
            for name in names:
                data[name][at] = p.cell_data[name][b]
        cells.append((kind, conn))
        for name in names:
            cell_data.setdefault(name, []).append(data[name])
    return StepFields(points, cells, point_data, cell_data)


def _vtk_array(name: str, arr: np.ndarray) -> str:
    kind = _VTK_TYPES[np.dtype(arr.dtype).str.lstrip("<>|=")]
    comps = int(np.prod(arr.shape[1:])) if arr.ndim > 1 else 1
    return f'      <PDataArray type="{kind}" Name={quoteattr(name)} NumberOfComponents="{comps}"/>'


def pvtu_text(piece: StepFields, sources: Sequence[str]) -> str:
    """The .pvtu that joins the VTU pieces ``sources`` (files next to it) into one grid for ParaView;
    ``piece``: one of them, whose fields every piece has."""
    first = {name: blocks[0] for name, blocks in piece.cell_data.items() if blocks}
    lines = ['<?xml version="1.0"?>',
             '<VTKFile type="PUnstructuredGrid" version="0.1" byte_order="LittleEndian">',
             '  <PUnstructuredGrid GhostLevel="0">', "    <PPointData>"]
    lines += [_vtk_array(name, arr) for name, arr in piece.point_data.items()]
    lines += ["    </PPointData>", "    <PCellData>"]
    lines += [_vtk_array(name, arr) for name, arr in first.items()]
    lines += ["    </PCellData>", "    <PPoints>", _vtk_array("Points", piece.points).replace(' Name="Points"', ""),
              "    </PPoints>"]
    lines += [f"    <Piece Source={quoteattr(src)}/>" for src in sources]
    lines += ["  </PUnstructuredGrid>", "</VTKFile>", ""]
    return "\n".join(lines)


def _pad_columns(arr: np.ndarray, width: int) -> np.ndarray:
    """(n, width - 1) -> (n, width) with a zero last column; anything else unchanged."""
    if arr.ndim == 2 and arr.shape[1] == width - 1:
        return np.concatenate([arr, np.zeros((arr.shape[0], 1), dtype=arr.dtype)], axis=1)
    return arr


def pad_cell_data(blocks_sizes: Sequence[int], data_per_block: Sequence[Mapping[str, np.ndarray]]
                  ) -> dict[str, list[np.ndarray]]:
    """Cell fields of every block, NaN where a block lacks a field (as VTU requires).

    blocks_sizes: cells per block; data_per_block: per block, name -> (n_block,) or (n_block, c).
    A field missing from some block becomes float64; otherwise its dtype is kept.
    """
    if len(blocks_sizes) != len(data_per_block):
        raise ValueError(f"{len(blocks_sizes)} block sizes for {len(data_per_block)} data blocks")
    tails: dict[str, tuple[int, ...]] = {}
    for b, (size, data) in enumerate(zip(blocks_sizes, data_per_block)):
        for name, arr in data.items():
            arr = np.asarray(arr)
            if arr.shape[0] != size:
                raise ValueError(f"cell field {name!r} of block {b} has {arr.shape[0]} rows for "
                                 f"{size} cells")
            if tails.setdefault(name, arr.shape[1:]) != arr.shape[1:]:
                raise ValueError(f"cell field {name!r} has components {arr.shape[1:]} in block {b} "
                                 f"but {tails[name]} before")
    out: dict[str, list[np.ndarray]] = {}
    for name, tail in tails.items():
        complete = all(name in data for data in data_per_block)
        out[name] = [np.asarray(data[name]) if complete else
                     np.asarray(data[name], dtype=np.float64) if name in data else
                     np.full((size, *tail), np.nan)
                     for size, data in zip(blocks_sizes, data_per_block)]
    return out


def crack_segments_from_points(x0: np.ndarray, x1: np.ndarray,
                               offset: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Extra points (2k, 3) and "line" connectivity (k, 2) of k segments x0[i] -> x1[i].

    x0, x1: (k, 2) or (k, 3) end points; 2D is padded with z = 0. Point 2i is x0[i], 2i + 1 is
    x1[i]; offset is the index of the first extra point (the number of mesh nodes).
    """
    x0 = np.asarray(x0, dtype=np.float64)
    x1 = np.asarray(x1, dtype=np.float64)
    if x0.shape != x1.shape or x0.ndim != 2 or x0.shape[1] not in (2, 3):
        raise ValueError(f"segment ends must both be (k, 2) or (k, 3), got {x0.shape} and "
                         f"{x1.shape}")
    pts = _pad_columns(np.stack([x0, x1], axis=1).reshape(-1, x0.shape[1]), 3)
    lines = offset + np.arange(pts.shape[0], dtype=np.int64).reshape(-1, 2)
    return pts, lines


def _local_coordinates(xe: np.ndarray, x: np.ndarray, cell_type: str) -> np.ndarray:
    """Reference coordinates (k, 2) of points x (k, 2) in cells with in-plane nodes xe (k, m, 2)."""
    if cell_type == "tri3":
        jac = np.stack([xe[:, 1] - xe[:, 0], xe[:, 2] - xe[:, 0]], axis=2)  # dx_i / dxi_j
        return np.linalg.solve(jac, (x - xe[:, 0])[..., None])[..., 0]
    signs = np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]])  # Q4 nodes, VTK order
    xi = np.zeros_like(x)
    scale = np.abs(xe).max(initial=1.0)
    for _ in range(30):  # Newton on x(xi) = x; exact in one step for parallelograms
        f = 0.5 * (1.0 + xi[:, None, :] * signs[None])  # (k, a, j)
        n = f[..., 0] * f[..., 1]  # (k, a)
        dn = 0.5 * signs[None] * f[..., ::-1]  # dN_a / dxi_j
        r = np.einsum("ka,kai->ki", n, xe) - x
        jac = np.einsum("kai,kaj->kij", xe, dn)
        step = np.linalg.solve(jac, r[..., None])[..., 0]
        xi -= step
        if np.abs(step).max(initial=0.0) < 1e-14 * max(1.0, scale):
            break
    return xi


def interpolate_nodal(values: np.ndarray, nodes: np.ndarray, cells: np.ndarray, cell_type: str,
                      host: np.ndarray, x: np.ndarray) -> np.ndarray:
    """N(x) d: nodal values (n_nodes, ...) interpolated at points x (k, 2|3) in cells host (k,).

    tri3 and quad4 use their shape functions. hex8 uses its bottom face (nodes 0-3, bilinear in
    x-y): a plane-strain section, as in the plots.
    """
    if cell_type not in MESHIO_TYPES:
        raise ValueError(f"unknown cell type {cell_type!r}; known: {sorted(MESHIO_TYPES)}")
    plane = cells[host, :3] if cell_type == "tri3" else cells[host, :4]  # (k, m)
    xi = _local_coordinates(nodes[plane][..., :2], np.asarray(x, dtype=np.float64)[:, :2],
                            "tri3" if cell_type == "tri3" else "quad4")
    if cell_type == "tri3":
        n = np.column_stack([1.0 - xi[:, 0] - xi[:, 1], xi[:, 0], xi[:, 1]])
    else:
        n = 0.25 * (1.0 + np.outer(xi[:, 0], [-1.0, 1.0, 1.0, -1.0])) * (
            1.0 + np.outer(xi[:, 1], [-1.0, -1.0, 1.0, 1.0]))
    vals = np.asarray(values, dtype=np.float64)[plane]  # (k, m, ...)
    return np.einsum("km,km...->k...", n, vals)


def step_fields(nodes: np.ndarray, cells: np.ndarray, cell_type: str, *,
                interfaces: np.ndarray | None = None,
                segments: tuple[np.ndarray, np.ndarray] | None = None,
                segment_cells: np.ndarray | None = None,
                point_data: Mapping[str, np.ndarray] | None = None,
                bulk_data: Mapping[str, np.ndarray] | None = None,
                interface_data: Mapping[str, np.ndarray] | None = None,
                segment_data: Mapping[str, np.ndarray] | None = None,
                segment_point_data: Mapping[str, np.ndarray] | None = None,
                triangles: np.ndarray | None = None,
                triangle_data: Mapping[str, np.ndarray] | None = None,
                triangle_point_data: Mapping[str, np.ndarray] | None = None) -> StepFields:
    """A step's grid: bulk cells, then interface quads, then embedded segments as lines, then
    embedded surfaces (3D) as triangles.

    nodes (n, dim), cells (n_el, m) of ``cell_type`` ("tri3", "quad4", "hex8");
    interfaces (n_if, 4) = (m0, m1, p0, p1), written as quads (m0, m1, p1, p0);
    segments = (x0, x1), (k, 2|3) end points of embedded cracks, in host cells segment_cells (k,);
    point_data: nodal fields (n, ...); at the segments' extra points segment_point_data (2k, ...)
        if given, else N d interpolated in the host cell, else NaN;
    triangles (k, 3, 3): vertices of the embedded surfaces' triangles, with point fields
        triangle_point_data (3k, ...) (NaN for the others);
    bulk_data, interface_data, segment_data, triangle_data: cell fields of each kind, NaN-padded to
    all cells.
    The field ``cell_kind`` (`CellKind`) is added. Empty kinds write no block.
    """
    if cell_type not in MESHIO_TYPES:
        raise ValueError(f"unknown cell type {cell_type!r}; known: {sorted(MESHIO_TYPES)}")
    nodes = np.asarray(nodes, dtype=np.float64)
    n_nodes, dim = nodes.shape
    blocks: list[tuple[str, np.ndarray]] = [(MESHIO_TYPES[cell_type], np.asarray(cells))]
    data: list[dict[str, np.ndarray]] = [dict(bulk_data or {})]
    kinds = [CellKind.BULK]
    if interfaces is not None and len(interfaces):
        itf = np.asarray(interfaces)
        if itf.shape[1] == 4:  # 2D (m0, m1, p0, p1) as the quad (m0, m1, p1, p0)
            blocks.append(("quad", itf[:, [0, 1, 3, 2]]))
        else:  # 3D: the minus face, then the plus face above it: a wedge or a hexahedron
            blocks.append(("wedge" if itf.shape[1] == 6 else "hexahedron", itf))
        data.append(dict(interface_data or {}))
        kinds.append(CellKind.INTERFACE)
    points = nodes
    extra_values: dict[str, np.ndarray] = {}
    if segments is not None and len(segments[0]):
        extra, lines = crack_segments_from_points(*segments, offset=n_nodes)
        points = np.concatenate([_pad_columns(nodes, 3), extra])
        blocks.append(("line", lines))
        data.append(dict(segment_data or {}))
        kinds.append(CellKind.EMBEDDED)
        given = dict(segment_point_data or {})
        for name, arr in (point_data or {}).items():
            if name in given:
                extra_values[name] = np.asarray(given[name])
            elif segment_cells is not None:
                host = np.repeat(np.asarray(segment_cells), 2)
                extra_values[name] = interpolate_nodal(arr, nodes, np.asarray(cells), cell_type,
                                                       host, extra)
            else:
                extra_values[name] = np.full((extra.shape[0], *np.shape(arr)[1:]), np.nan)
    if triangles is not None and len(triangles):
        first = points.shape[0] if points is not nodes else n_nodes
        if points is nodes:
            points = _pad_columns(nodes, 3)
        tri = np.asarray(triangles, dtype=np.float64).reshape(-1, 3)
        points = np.concatenate([points, tri])
        blocks.append(("triangle", first + np.arange(tri.shape[0], dtype=np.int64).reshape(-1, 3)))
        data.append(dict(triangle_data or {}))
        kinds.append(CellKind.EMBEDDED)
        given = dict(triangle_point_data or {})
        for name, arr in (point_data or {}).items():
            here = np.asarray(given[name]) if name in given else np.full((tri.shape[0], *np.shape(arr)[1:]), np.nan)
            extra_values[name] = (here if name not in extra_values
                                  else np.concatenate([extra_values[name], here]))
    pdata = {}
    for name, arr in (point_data or {}).items():
        arr = np.asarray(arr)
        if name in extra_values:
            arr = np.concatenate([arr, extra_values[name].astype(np.result_type(arr, np.float64))])
        pdata[name] = _pad_columns(arr, 3) if dim == 2 else arr
    sizes = [b[1].shape[0] for b in blocks]
    for d, kind, size in zip(data, kinds, sizes):
        d["cell_kind"] = np.full(size, int(kind), dtype=np.int8)
    return StepFields(points, blocks, pdata, pad_cell_data(sizes, data))


class VtkSeries:
    """``folder/<name>_<step:05d>.vtu`` per step and ``folder/<name>.pvd`` listing them with times.

    Each file is written to a temporary name and moved into place (os.replace), the VTU first and
    the .pvd after it, so a run that stops at any moment leaves a valid series of whole files.
    A new series (``resume=False``) deletes the folder's old ``<name>_<digits>.vtu`` files and
    .pvd; ``resume=True`` continues the series in the existing .pvd (call `truncate_after`
    with the step resumed from). ``compression``: "zlib" (default), "lzma" or None (faster, larger).
    """

    def __init__(self, folder: str | Path, name: str = "results", *, resume: bool = False,
                 compression: str | None = "zlib", rank: int = 0, ranks: int = 1):
        """rank, ranks: a series written in pieces by the ranks of an MPI run (:meth:`write_piece`);
        rank 0 keeps the .pvd and deletes old files."""
        self.folder = Path(folder)
        self.name = name
        self.compression = compression
        self.rank, self.ranks = rank, ranks
        self.pvd = self.folder / f"{name}.pvd"
        self._pattern = re.compile(re.escape(name) + r"_(\d{5,})(?:_p\d+)?\.p?vtu")
        self.entries: list[tuple[int, float, str]] = []  # (step, time, file name), steps increasing
        self.folder.mkdir(parents=True, exist_ok=True)
        if rank != 0:
            return
        if resume and self.pvd.exists():
            self.entries = self._read_pvd()
        else:
            self._delete_files(lambda step: True)
        self._write_pvd()

    def write(self, step: int, time: float, mesh_arrays: StepFields) -> Path:
        """Write the step's VTU, then list it in the .pvd; steps must increase. Returns its path."""
        if self.entries and step <= self.entries[-1][0]:
            raise ValueError(f"step {step} is not after the last written step {self.entries[-1][0]}"
                             " (call truncate_after first to rewrite steps)")
        if not np.isfinite(time):
            raise ValueError(f"time of step {step} is {time}")
        file = f"{self.name}_{step:05d}.vtu"
        tmp = self.folder / f".{file}.tmp"
        meshio.vtu.write(str(tmp), mesh_arrays.to_meshio(), binary=True,
                         compression=self.compression)
        os.replace(tmp, self.folder / file)
        self.entries.append((int(step), float(time), file))
        self._write_pvd()
        return self.folder / file

    def write_piece(self, step: int, time: float, piece: StepFields, written: Callable[[], None]) -> None:
        """Every rank: write this rank's piece of the step (``<name>_<step>_p<rank>.vtu``); once
        ``written()`` returns (a barrier: every rank's piece is there), rank 0 writes the step's
        ``.pvtu`` that joins them and lists it in the .pvd."""
        if not np.isfinite(time):
            raise ValueError(f"time of step {step} is {time}")
        stem = f"{self.name}_{step:05d}"
        file = f"{stem}_p{self.rank}.vtu"
        tmp = self.folder / f".{file}.tmp"
        meshio.vtu.write(str(tmp), piece.to_meshio(), binary=True, compression=self.compression)
        os.replace(tmp, self.folder / file)
        written()
        if self.rank != 0:
            return
        if self.entries and step <= self.entries[-1][0]:
            raise ValueError(f"step {step} is not after the last written step {self.entries[-1][0]}")
        tmp = self.folder / f".{stem}.pvtu.tmp"
        tmp.write_text(pvtu_text(piece, [f"{stem}_p{r}.vtu" for r in range(self.ranks)]))
        os.replace(tmp, self.folder / f"{stem}.pvtu")
        self.entries.append((int(step), float(time), f"{stem}.pvtu"))
        self._write_pvd()

    def truncate_after(self, step: int) -> None:
        """After ``step``: delete their VTU files, listed or not; rewrite the .pvd (rank 0's work)."""
        if self.rank != 0:
            return
        self.entries = [e for e in self.entries if e[0] <= step]
        self._delete_files(lambda s: s > step)
        self._write_pvd()

    def _delete_files(self, select) -> None:
        for entry in os.scandir(self.folder):
            match = self._pattern.fullmatch(entry.name)
            if match and select(int(match.group(1))):
                os.remove(entry.path)

    def _write_pvd(self) -> None:
        lines = ['<?xml version="1.0"?>',
                 '<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">',
                 "  <Collection>"]
        lines += [f'    <DataSet timestep="{time!r}" group="" part="0" file={quoteattr(file)}/>'
                  for _, time, file in self.entries]
        lines += ["  </Collection>", "</VTKFile>", ""]
        tmp = self.folder / f".{self.pvd.name}.tmp"
        tmp.write_text("\n".join(lines))
        os.replace(tmp, self.pvd)

    def _read_pvd(self) -> list[tuple[int, float, str]]:
        entries = []
        for ds in ET.parse(self.pvd).getroot().iter("DataSet"):
            file = ds.get("file", "")
            match = self._pattern.fullmatch(file)
            if match is None or "_p" in file[len(self.name):]:
                raise ValueError(f"{self.pvd}: {file!r} is not a file of the series {self.name!r}")
            entries.append((int(match.group(1)), float(ds.get("timestep", "nan")), file))
        return sorted(entries)
