"""Cohesive-surface insertion in 3D: split a tet4 or hex8 mesh along chosen internal faces.

The 3D counterpart of :mod:`rockfrac.mesh.interfaces`. Faces shared by two cells are numbered once
by :func:`internal_faces`; a selection is a boolean mask over that numbering. :func:`insert_faces`
duplicates the nodes on the selected faces and returns a new :class:`Mesh` with one interface
cell per selected face: ``(m_0 .. m_{k-1}, p_0 .. p_{k-1})``, k = 3 (triangles) or 4
(quadrilaterals), the minus face ordered outward from the minus cell (its right-hand normal
points into the plus cell) and p_j the plus-side copy of m_j.

How nodes are split: around every node on a selected face, its incident cells are grouped into
fans, two cells joined when they share a face through the node that is not selected; the fan
holding the lowest-numbered cell keeps the node, every other fan gets a copy (the 2D rule of
:mod:`rockfrac.mesh.interfaces`, with faces for edges). So a node on the front of a crack that ends
inside the body (one fan) is not split, a node where a crack meets the boundary is, and along an
edge where three or more cracks meet each node gets one copy per wedge of cells between them.
"""

from __future__ import annotations

from dataclasses import replace
from typing import NamedTuple

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from rockfrac.mesh.interfaces import (
    _region_mask,
    _selected_indices,
    copied_node_sets,
    minus_and_plus,
    region_labels,
    split_cut_nodes,
)
from rockfrac.mesh.mesh import Mesh
from rockfrac.mesh.topology import CELL_FACES, same_nodes


class InternalFaces(NamedTuple):
    """Faces shared by two cells: faces (k, m) nodes, outward from cells[:, 0]; cells (k, 2) the two
    cells (lower index first); local (k, 2) the face's local index in each cell."""

    faces: np.ndarray
    cells: np.ndarray
    local: np.ndarray


def internal_faces(mesh: Mesh) -> InternalFaces:
    """Every face shared by two cells of a 3D mesh; ValueError for a 2D mesh or a face of > 2 cells."""
    if mesh.dim != 3:
        raise ValueError(f"internal_faces is for 3D meshes; this one is {mesh.dim}D (see internal_edges)")
    local_faces = CELL_FACES[mesh.cells.shape[1]]
    nf, m = local_faces.shape
    sides = mesh.cells[:, local_faces].reshape(-1, m)
    ids = same_nodes(sides)
    order = np.argsort(ids, kind="stable")  # equal faces: lower cell first
    k = ids[order]
    same = k[1:] == k[:-1]
    if np.any(same[1:] & same[:-1]):
        raise ValueError("a face is shared by more than two cells (non-manifold mesh)")
    first, second = order[:-1][same], order[1:][same]
    return InternalFaces(sides[first], np.stack([first // nf, second // nf], axis=1),
                         np.stack([first % nf, second % nf], axis=1))


def all_faces(mesh: Mesh) -> np.ndarray:
    """Every internal face (a fully fragmentable body)."""
    return np.ones(internal_faces(mesh).faces.shape[0], dtype=bool)


def faces_on_region_boundaries(mesh: Mesh) -> np.ndarray:
    """Internal faces whose two cells lie in different regions (every grain boundary at once)."""
    label = region_labels(mesh)
    c = internal_faces(mesh).cells
    return label[c[:, 0]] != label[c[:, 1]]


def faces_within(mesh: Mesh, region) -> np.ndarray:
    """Internal faces whose two cells both lie in ``region`` (name, cell indices or mask)."""
    return _region_mask(mesh, region)[internal_faces(mesh).cells].all(axis=1)


def faces_between(mesh: Mesh, region_a, region_b) -> np.ndarray:
    """Internal faces with one cell in ``region_a`` and the other in ``region_b``."""
    a, b = _region_mask(mesh, region_a), _region_mask(mesh, region_b)
    c = internal_faces(mesh).cells
    return (a[c[:, 0]] & b[c[:, 1]]) | (a[c[:, 1]] & b[c[:, 0]])


def faces_on(mesh: Mesh, faces: np.ndarray) -> np.ndarray:
    """Internal faces holding the same nodes as a row of ``faces`` (e.g. a physical surface's face set)."""
    own = internal_faces(mesh).faces
    ids = same_nodes(np.vstack([own, np.asarray(faces, dtype=np.int64).reshape(-1, own.shape[1])]))
    return np.isin(ids[: len(own)], ids[len(own):])


def minus_side(mesh: Mesh, selected: np.ndarray, region) -> np.ndarray:
    """Minus cell of each selected face: its cell in ``region`` (the first cell if both or neither)."""
    f = internal_faces(mesh)
    c = f.cells[_selected_indices(selected, f.faces.shape[0])]
    inside = _region_mask(mesh, region)[c]
    return np.where(inside[:, 1] & ~inside[:, 0], c[:, 1], c[:, 0])


def _fans(cells: np.ndarray, f: InternalFaces, keep: np.ndarray) -> np.ndarray:
    """Component label per (cell, corner) incidence, flat (n_cells n_corners,): the incidences of a
    node in two cells are joined across every internal face in ``keep`` that holds the node."""
    nc, nv = cells.shape
    local_faces = CELL_FACES[nv]
    c0, c1 = f.cells[keep, 0], f.cells[keep, 1]
    corners0 = local_faces[f.local[keep, 0]]  # (k, m) corners of the face in c0
    nodes0 = cells[c0[:, None], corners0]
    # the corner of each of those nodes in c1
    corners1 = np.argmax(cells[c1][:, None, :] == nodes0[:, :, None], axis=2)
    rows = (c0[:, None] * nv + corners0).ravel()
    cols = (c1[:, None] * nv + corners1).ravel()
    graph = sp.coo_matrix((np.ones(rows.size, dtype=np.int8), (rows, cols)), shape=(nc * nv,) * 2)
    return connected_components(graph, directed=False)[1]


def _follow_faces(old: np.ndarray, new: np.ndarray, faces: np.ndarray, split: np.ndarray) -> np.ndarray:
    """Renumber faces (k, m) with the copies of the cell that holds them (the first such cell): a
    boundary face has one; a face inside the body keeps the numbering of its lower cell."""
    if faces.size == 0:
        return faces.copy()
    local_faces = CELL_FACES[old.shape[1]]
    nf, m = local_faces.shape
    sides = old[:, local_faces].reshape(-1, m)
    ids = same_nodes(np.vstack([sides, faces]))
    side_ids, query = ids[: len(sides)], ids[len(sides):]
    first = np.full(ids.max() + 1, -1)
    first[side_ids[::-1]] = np.arange(len(sides))[::-1]  # the lowest flat index of each face
    hit = first[query]
    if np.any((hit < 0) & split[faces].any(axis=1)):
        raise ValueError("a face of a face set on a split node is not a face of any cell; cannot tell "
                         "which copy it follows")
    out = faces.copy()
    ok = hit >= 0
    cell, lf = hit[ok] // nf, hit[ok] % nf
    old_nodes, new_nodes = old[cell], new[cell]
    pos = np.argmax(old_nodes[:, None, :] == faces[ok][:, :, None], axis=2)  # (k, m) corner of each node
    out[ok] = np.take_along_axis(new_nodes, pos, axis=1)
    return out


def insert_faces(mesh: Mesh, selected: np.ndarray, minus_cells: np.ndarray | None = None) -> Mesh:
    """Split a 3D ``mesh`` along the selected internal faces; a new Mesh with the interface cells.

    selected: boolean mask over :func:`internal_faces` (or their indices). minus_cells: the minus
    cell of each selected face (default: the first of the pair). Node sets gain the copies of their
    nodes; face sets follow the copies of the cell holding each face; regions are kept. The mesh must
    have no interfaces yet.
    """
    if mesh.interfaces.size:
        raise ValueError("insert_faces splits a mesh without interfaces; select every set at once")
    f = internal_faces(mesh)
    s = _selected_indices(selected, f.faces.shape[0])
    cells, n = mesh.cells, mesh.n_nodes
    pair, local = f.cells[s], f.local[s]
    mc, pc, lm = minus_and_plus(pair, local, minus_cells, "face")
    keep = np.ones(f.faces.shape[0], dtype=bool)
    keep[s] = False
    new_cells, parent, split = split_cut_nodes(cells, _fans(cells, f, keep), f.faces[s], n)

    corners = CELL_FACES[cells.shape[1]][lm]  # (k, m) outward from the minus cell
    minus = new_cells[mc[:, None], corners]
    old_nodes = cells[mc[:, None], corners]
    plus_corner = np.argmax(cells[pc][:, None, :] == old_nodes[:, :, None], axis=2)
    plus = np.take_along_axis(new_cells[pc], plus_corner, axis=1)

    node_sets = copied_node_sets(mesh.node_sets, parent, n)
    face_sets = {name: _follow_faces(cells, new_cells, np.asarray(fs, dtype=np.int64), split)
                 for name, fs in mesh.face_sets.items()}
    return replace(mesh, nodes=mesh.nodes[parent], cells=new_cells, interfaces=np.concatenate([minus, plus], axis=1),
                   node_sets=node_sets, face_sets=face_sets,
                   regions={k: np.array(v, copy=True) for k, v in mesh.regions.items()})
