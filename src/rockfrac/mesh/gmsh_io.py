"""Read Gmsh meshes (.msh, any version Gmsh reads) into a :class:`Mesh`, through Gmsh's Python API.

What :func:`read_mesh` makes of a file:

- Cells: every element of dimension ``dim`` (2, 3, or None: the file's highest; elements of a
  higher dimension are an error); they must be of one supported type (2D: tri3 from Gmsh
  "Triangle 3" or quad4 from "Quadrilateral 4"; 3D: tet4 from "Tetrahedron 4" or hex8 from
  "Hexahedron 8"). Nodes on no
  cell (geometry points, ...) are dropped and the rest renumbered compactly, in Gmsh's order.
  2D meshes must lie in a plane z = const; z is dropped.
- Orientation: the Jacobian is evaluated at every corner of every cell. A cell with all corner
  Jacobians negative (a clockwise triangle or quadrilateral, as Gmsh makes on a surface whose
  normal is -z; a mirrored hexahedron) is valid but mis-ordered: its node order is reversed
  (logged at INFO). A cell with a zero or mixed-sign corner Jacobian (degenerate, bow-tie,
  inverted) is an error naming its Gmsh element tag and position.
- regions: one per physical group of the top dimension (physical surface in 2D, volume in 3D),
  name -> cell indices. A cell in no such group is an error (a user mesh must say which material
  each cell is), unless the file has no group of the top dimension at all: then one region "bulk".
  Regions overlap where the file's groups do.
- node_sets: one per physical group of lower dimension (curves and points in 2D; surfaces, curves
  and points in 3D): the nodes of its elements (groups of the same name are merged).
- edge_sets (2D): one per physical curve, its line elements as node pairs. An edge on the boundary
  of the body is oriented counter-clockwise around it (body on the left: the direction in which
  its counter-clockwise cell runs through it), so its outward normal is (dy, -dx)/L. An edge
  inside the body (an internal curve, e.g. a grain boundary or a future crack) keeps Gmsh's
  orientation: **pressure loads only make sense on boundary edges** -- check with
  :func:`on_boundary`; :func:`boundary_edges` lists all of them.
- face_sets (3D): one per physical surface, its quadrilaterals (hex8) or triangles (tet4), oriented
  outward (right-hand normal) by the adjacent cell where on the boundary.
- Unnamed physical groups are named by their number, e.g. "3".

Every problem raises :class:`rockfrac.case.schema.CaseError` naming the file, what is wrong and
what is allowed. :func:`require_groups` does the same for groups a case asks for. Gmsh is one
process-wide state: read from one thread at a time.

Why Gmsh and not meshio: meshio 5.3 fails on MSH 4.1 files saved with Mesh.SaveAll = 1 when some
entities are in no physical group, keeps one of two groups of the same name, and returns the
repeated elements of MSH 2 files twice; Gmsh reads every version the way Gmsh wrote it.

Example::

    mesh = read_mesh("grains.msh")
    require_groups(mesh, ["top", "bottom"], "grains.msh", kind="edge_sets")
"""

from __future__ import annotations

import logging
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np

from rockfrac.errors import CaseError
from rockfrac.files import check_file
from rockfrac.mesh.geometry import corner_jacobians
from rockfrac.mesh.mesh import Mesh
from rockfrac.mesh.topology import (  # noqa: F401 (boundary_edges, boundary_faces, on_boundary: re-exported)
    boundary_edges,
    boundary_faces,
    cell_sides,
    match,
    on_boundary,
    same_nodes,
)

__all__ = ["boundary_edges", "boundary_faces", "gmsh_session", "mesh_from_model", "on_boundary",
           "read_mesh", "require_groups"]

log = logging.getLogger(__name__)

CELL_TYPES = {"Triangle 3": "tri3", "Quadrilateral 4": "quad4", "Tetrahedron 4": "tet4", "Hexahedron 8": "hex8"}
ALLOWED = {2: ("tri3", "quad4"), 3: ("tet4", "hex8")}
SIDE = {"tri3": "Line 2", "quad4": "Line 2", "tet4": "Triangle 3", "hex8": "Quadrilateral 4"}  # Gmsh's side type
GMSH_NAME = {v: k for k, v in CELL_TYPES.items()}
# each cell type reversed: the mirror image of the same cell
REVERSED = {"tri3": [0, 2, 1], "quad4": [0, 3, 2, 1], "tet4": [0, 2, 1, 3], "hex8": [0, 3, 2, 1, 4, 7, 6, 5]}
DIM_WORD = {0: "point", 1: "curve", 2: "surface", 3: "volume"}
GroupKind = Literal["node_sets", "edge_sets", "face_sets", "regions"]


@dataclass
class _Block:
    """The elements of one type on one Gmsh entity: tags (k,), node tags (k, n_nodes)."""

    dim: int
    entity: int
    name: str  # Gmsh's element type name, e.g. "Triangle 3"
    tags: np.ndarray
    nodes: np.ndarray


@dataclass
class _Group:
    """A physical group: dimension, name (its number if unnamed), the entities it holds."""

    dim: int
    name: str
    entities: np.ndarray


@dataclass
class _Raw:
    """What the Gmsh model holds: node tags (n,), coordinates (n, 3), element blocks, groups."""

    node_tags: np.ndarray
    coords: np.ndarray
    blocks: list[_Block]
    groups: list[_Group]


@contextmanager
def gmsh_session(model: str = "rockfrac") -> Iterator[None]:
    """Work in a fresh, quiet Gmsh model; initialize and finalize Gmsh unless the caller has.

    If Gmsh is already initialized, the caller's models and General.Terminal are left as found.
    """
    import gmsh

    own = not gmsh.isInitialized()
    if own:
        gmsh.initialize(readConfigFiles=False, interruptible=False)
        previous, terminal = "", 0.0
    else:
        previous, terminal = gmsh.model.getCurrent(), gmsh.option.getNumber("General.Terminal")
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.model.add(model)
    try:
        yield
    finally:
        if own:
            gmsh.finalize()
        else:
            gmsh.model.setCurrent(model)
            gmsh.model.remove()
            gmsh.model.setCurrent(previous)
            gmsh.option.setNumber("General.Terminal", terminal)


MSH_HEADER = b"$MeshFormat"


def check_msh(path: str | Path) -> Path:
    """``path`` if it is a Gmsh mesh file (.msh, starting with $MeshFormat, ASCII or binary);
    CaseError otherwise. Gmsh *runs* .geo files and other scripts it is given (their SystemCall
    and Shell commands reach the shell), so only mesh files, which are data, are handed to it."""
    path = check_file(path, "a Gmsh mesh file (.msh)")
    if path.suffix.lower() != ".msh":
        raise CaseError(f"{path}: only Gmsh .msh mesh files are read (a {path.suffix or 'suffix-less'} file is "
                        "refused: Gmsh would run a .geo or other script, shell calls included); mesh it first, "
                        "e.g. gmsh -2 file.geo -o file.msh")
    with open(path, "rb") as fh:
        head = fh.read(256).lstrip()
    if not head.startswith(MSH_HEADER):
        raise CaseError(f"{path}: not a Gmsh mesh file (it does not start with $MeshFormat); only .msh meshes "
                        "are read, never scripts")
    return path


def read_mesh(path: str | Path, *, dim: int | None = 2) -> Mesh:
    """Read a Gmsh .msh file into a Mesh (see the module docstring); CaseError on any problem.

    dim: the mesh's dimension, 2 or 3; None takes the highest dimension of the file's elements.
    """
    if dim not in (2, 3, None):
        raise ValueError(f"dim must be 2, 3 or None, got {dim}")
    check_msh(path)
    import gmsh

    with gmsh_session("rockfrac_read"):
        try:
            gmsh.merge(str(path))
        except Exception as err:  # noqa: BLE001 (Gmsh raises a bare Exception with its message)
            raise CaseError(f"{path}: not a mesh Gmsh can read: {err}") from None
        return mesh_from_model(dim=dim, source=str(path))


def mesh_from_model(*, dim: int | None = 2, source: str = "gmsh model") -> Mesh:
    """The Mesh of Gmsh's current model (meshed), as :func:`read_mesh` describes; ``source``
    names it in error messages."""
    return _to_mesh(_collect(), dim, source)


def _collect() -> _Raw:
    """Nodes, element blocks and physical groups of Gmsh's current model."""
    import gmsh

    tags, coords, _ = gmsh.model.mesh.getNodes()
    blocks = []
    for d, e in gmsh.model.getEntities():
        types, elem_tags, elem_nodes = gmsh.model.mesh.getElements(d, e)
        for t, et, en in zip(types, elem_tags, elem_nodes, strict=True):
            name = gmsh.model.mesh.getElementProperties(t)[0]
            blocks.append(_Block(d, e, name, np.asarray(et, np.int64),
                                 np.asarray(en, np.int64).reshape(len(et), -1)))
    groups = [_Group(d, gmsh.model.getPhysicalName(d, t) or str(t),
                     np.asarray(gmsh.model.getEntitiesForPhysicalGroup(d, t), np.int64))
              for d, t in gmsh.model.getPhysicalGroups()]
    return _Raw(np.asarray(tags, np.int64), np.asarray(coords).reshape(-1, 3), blocks, groups)


def _to_mesh(raw: _Raw, dim: int | None, source: str) -> Mesh:
    if dim is None:
        dim = max((b.dim for b in raw.blocks), default=0)
        if dim not in ALLOWED:
            raise CaseError(f"{source}: no 2D or 3D cells; the file has {_summary(raw.blocks)}")
    cell_type, tags, entity, cell_nodes = _bulk(raw, dim, source)
    regions = _regions(raw, dim, entity, tags, source)
    used, cells = np.unique(cell_nodes, return_inverse=True)  # node tags on cells, sorted
    cells = cells.reshape(cell_nodes.shape)
    nodes = _coordinates(raw, used, dim, source)
    cells = _orient(nodes, cells, cell_type, tags, source)
    node_sets, sides = _lower_groups(raw, dim, used, SIDE[cell_type], source)
    mesh = Mesh(nodes=nodes, cells=cells, cell_type=cell_type, node_sets=node_sets, regions=regions)
    all_sides = cell_sides(cells, dim)
    for name, group in sides.items():
        oriented = _orient_sides(all_sides, group, name, nodes, source)
        (mesh.edge_sets if dim == 2 else mesh.face_sets)[name] = oriented
    problems = mesh.check()
    if problems:
        raise CaseError(f"{source}: {'; '.join(problems)}")
    return mesh


def _summary(blocks: list[_Block]) -> str:
    counts: dict[str, int] = {}
    for b in blocks:
        counts[b.name] = counts.get(b.name, 0) + len(b.tags)
    return ", ".join(f"{n} x '{name}'" for name, n in counts.items()) or "no elements"


def _bulk(raw: _Raw, dim: int, source: str) -> tuple[str, np.ndarray, np.ndarray, np.ndarray]:
    """The cell type, Gmsh tags (k,), entities (k,) and node tags (k, n) of the top-dim elements."""
    top = max((b.dim for b in raw.blocks), default=-1)
    allowed = " or ".join(f"{t} ('{GMSH_NAME[t]}')" for t in ALLOWED[dim])
    if top > dim:
        raise CaseError(f"{source}: the mesh has {top}D elements but a {dim}D mesh was asked for "
                        f"(dim={dim}); its elements: {_summary(raw.blocks)}")
    blocks = [b for b in raw.blocks if b.dim == dim]
    if not blocks:
        raise CaseError(f"{source}: no {dim}D cells; a {dim}D mesh needs {allowed} cells; "
                        f"the file has {_summary(raw.blocks)}")
    names = {b.name for b in blocks}
    if len(names) > 1 or CELL_TYPES.get(names.pop()) not in ALLOWED[dim]:
        raise CaseError(f"{source}: the {dim}D cells must all be of one type, {allowed}; "
                        f"found {_summary(blocks)}")
    tags = np.concatenate([b.tags for b in blocks])
    entity = np.concatenate([np.full(len(b.tags), b.entity) for b in blocks])
    nodes = np.vstack([b.nodes for b in blocks])
    # MSH 2 files repeat an element once per physical group: keep the first copy
    _, first = np.unique(same_nodes(nodes), return_index=True)
    keep = np.sort(first)
    return CELL_TYPES[blocks[0].name], tags[keep], entity[keep], nodes[keep]


def _regions(raw: _Raw, dim: int, entity: np.ndarray, tags: np.ndarray, source: str) -> dict:
    groups = [g for g in raw.groups if g.dim == dim]
    if not groups:
        return {"bulk": np.arange(len(entity))}
    masks: dict[str, np.ndarray] = {}
    for g in groups:
        masks[g.name] = masks.get(g.name, np.zeros(len(entity), bool)) | np.isin(entity, g.entities)
    orphan = ~np.logical_or.reduce(list(masks.values()))
    if orphan.any():
        ents = sorted(set(entity[orphan].tolist()))
        word = DIM_WORD[dim]
        first = tags[orphan][:5].tolist()
        raise CaseError(
            f"{source}: {orphan.sum()} of {len(entity)} cells (Gmsh elements {first}"
            f"{', ...' if orphan.sum() > 5 else ''}; {word}s {ents}) belong to no physical {word}; "
            f"every cell needs a region (material): add {word}s {ents} to a physical {word} "
            f"(physical {word}s in the file: {', '.join(repr(n) for n in masks)})")
    return {name: np.flatnonzero(m) for name, m in masks.items()}


def _coordinates(raw: _Raw, used: np.ndarray, dim: int, source: str) -> np.ndarray:
    order = np.argsort(raw.node_tags)
    pos = np.searchsorted(raw.node_tags, used, sorter=order)
    x = raw.coords[order[np.minimum(pos, len(order) - 1)]]
    if dim == 3:
        return x
    z = x[:, 2]
    scale = max(np.ptp(x[:, :2], axis=0).max(), 1e-300)
    if np.ptp(z) > 1e-9 * scale:
        raise CaseError(f"{source}: a 2D mesh must lie in a plane z = const; its nodes have z from "
                        f"{z.min():g} to {z.max():g}")
    return x[:, :2].copy()


def _point(x: np.ndarray) -> str:
    return f"({', '.join(f'{v:.4g}' for v in x)})"


def _corner_jacobians(nodes: np.ndarray, cells: np.ndarray, cell_type: str) -> np.ndarray:
    """det J at every corner of every cell, (n_cells, n_corners)."""
    return corner_jacobians(nodes, cells, cell_type)


def _orient(nodes: np.ndarray, cells: np.ndarray, cell_type: str, tags: np.ndarray,
            source: str) -> np.ndarray:
    """Reverse the node order of mirrored cells; CaseError for degenerate or inverted ones."""
    det = _corner_jacobians(nodes, cells, cell_type)
    scale = np.ptp(nodes, axis=0).max() ** nodes.shape[1]
    tol = 1e-12 * scale
    positive, negative = (det > tol).all(axis=1), (det < -tol).all(axis=1)
    bad = np.flatnonzero(~(positive | negative))
    if bad.size:
        where = "; ".join(f"element {tags[c]} at {_point(nodes[cells[c]].mean(axis=0))}"
                          for c in bad[:3])
        raise CaseError(f"{source}: {bad.size} degenerate or inverted cells (zero or mixed-sign "
                        f"Jacobian within the cell): {where}{'; ...' if bad.size > 3 else ''}; "
                        "every cell must be convex with distinct corners")
    if negative.any():
        log.info("%s: reversed the node order of %d mirrored (clockwise) cells", source,
                 negative.sum())
        cells = cells.copy()
        cells[negative] = cells[negative][:, REVERSED[cell_type]]
    return cells


def _lower_groups(raw: _Raw, dim: int, used: np.ndarray, side: str, source: str) -> tuple[dict, dict]:
    """Node sets of the lower-dimensional groups, and the (k, 2) edges / (k, 4) or (k, 3) faces
    (Gmsh element type ``side``) of the groups one dimension down, in compact node numbers (Gmsh's
    orientation)."""
    node_sets: dict[str, np.ndarray] = {}
    sides: dict[str, np.ndarray] = {}
    for g in raw.groups:
        if g.dim >= dim:
            continue
        entities = set(g.entities.tolist())
        blocks = [b for b in raw.blocks if b.dim == g.dim and b.entity in entities]
        tags = np.concatenate([b.nodes.ravel() for b in blocks] + [np.zeros(0, np.int64)])
        pos = np.minimum(np.searchsorted(used, tags), len(used) - 1)
        missing = used[pos] != tags
        word = DIM_WORD[g.dim]
        if missing.any():
            n_free = len(np.unique(tags[missing]))
            raise CaseError(
                f"{source}: physical {word} {g.name!r} has {n_free} nodes on no {dim}D cell: its "
                f"elements must be sides of the cells. Is part of the body in no physical "
                f"{DIM_WORD[dim]}? (Gmsh saves only the elements of physical groups unless "
                "Mesh.SaveAll = 1)")
        node_sets[g.name] = np.union1d(node_sets.get(g.name, np.zeros(0, np.int64)), pos)
        if g.dim == dim - 1:
            wrong = [b for b in blocks if b.name != side]
            if wrong:
                raise CaseError(f"{source}: physical {word} {g.name!r} holds {_summary(wrong)}; "
                                f"its elements must be '{side}' (sides of the {dim}D cells)")
            k = pos.reshape(-1, {"Line 2": 2, "Triangle 3": 3, "Quadrilateral 4": 4}[side])
            k = np.vstack([sides[g.name], k]) if g.name in sides else k
            sides[g.name] = k[np.sort(np.unique(same_nodes(k), return_index=True)[1])]  # MSH 2
    return node_sets, sides


def _orient_sides(sides: np.ndarray, group: np.ndarray, name: str, nodes: np.ndarray,
                  source: str) -> np.ndarray:
    """The group's sides, those on the boundary oriented as their cell's side."""
    row, count = match(sides, group)
    if (row < 0).any():
        at = _point(nodes[group[row < 0][0]].mean(axis=0))
        raise CaseError(f"{source}: physical group {name!r} has {(row < 0).sum()} elements that "
                        f"are no side of any cell (the first near {at}): the mesh must be "
                        "conforming along it")
    out = group.copy()
    boundary = count == 1
    out[boundary] = sides[row[boundary]]
    return out


KIND_WORDS = {"regions": "a region (a physical surface in 2D, volume in 3D)",
              "edge_sets": "an edge set (a physical curve)",
              "face_sets": "a face set (a physical surface of a 3D mesh)",
              "node_sets": "a node set (a physical group of points, curves or surfaces)"}


def require_groups(mesh: Mesh, names: Iterable[str], path: str | Path,
                   *, kind: GroupKind | None = None) -> None:
    """CaseError unless every name is a group of the mesh (of ``kind`` if given, else of any
    kind), listing the groups the file has, e.g. "grains.msh: physical group 'top' not found;
    groups in the file: regions 'grains', 'matrix'; edge sets ..."."""
    kinds: list[GroupKind] = [kind] if kind else ["regions", "edge_sets", "face_sets", "node_sets"]
    have = set().union(*(getattr(mesh, k) for k in kinds))
    missing = [n for n in names if n not in have]
    if not missing:
        return
    what = (f"physical group {missing[0]!r} not found" if len(missing) == 1
            else f"physical groups {', '.join(repr(n) for n in missing)} not found")
    if kind:
        what += f" as {KIND_WORDS[kind]}"
    listing = "; ".join(f"{k.replace('_', ' ')} {', '.join(map(repr, sorted(getattr(mesh, k))))}"
                        for k in ("regions", "edge_sets", "face_sets", "node_sets")
                        if getattr(mesh, k))
    raise CaseError(f"{path}: {what}; groups in the file: {listing or 'none'}")
