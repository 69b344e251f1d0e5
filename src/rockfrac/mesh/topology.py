"""Mesh topology: cell sides, the boundary, and the outer boundary of a mesh with cohesive cracks."""

from __future__ import annotations

import numpy as np

from rockfrac.mesh.mesh import Mesh

# hexahedron and tetrahedron faces (VTK order), each with its right-hand normal out of the cell
HEX_FACES = np.array([[0, 3, 2, 1], [4, 5, 6, 7], [0, 1, 5, 4],
                      [1, 2, 6, 5], [2, 3, 7, 6], [3, 0, 4, 7]])
TET_FACES = np.array([[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]])
CELL_FACES = {8: HEX_FACES, 4: TET_FACES}  # by the number of nodes of a 3D cell


def cell_sides(cells: np.ndarray, dim: int) -> np.ndarray:
    """Every side of every cell, oriented with the cell on its left (2D: (n_cells * n, 2) edges of
    counter-clockwise cells) or outward (3D: (n_cells * 6, 4) hexahedron faces, (n_cells * 4, 3)
    tetrahedron faces)."""
    if dim == 2:
        return np.stack([cells, np.roll(cells, -1, axis=1)], axis=-1).reshape(-1, 2)
    faces = CELL_FACES[cells.shape[1]]
    return cells[:, faces].reshape(-1, faces.shape[1])


def same_nodes(rows: np.ndarray) -> np.ndarray:
    """An id per row of node indices (k, m), equal for rows holding the same nodes in any order.

    Sorted rows are packed two columns per int64 key (a * n + b) and lexsorted: several times
    faster than np.unique(axis=0).
    """
    r = np.sort(np.asarray(rows, dtype=np.int64), axis=1)
    if len(r) == 0:
        return np.zeros(0, np.int64)
    n = r.max() + 1
    keys = [r[:, j] * n + r[:, j + 1] for j in range(0, r.shape[1] - 1, 2)]
    if r.shape[1] % 2:
        keys.append(r[:, -1])
    order = np.lexsort(keys[::-1])  # the first key is the primary one
    new = np.zeros(len(r), bool)
    new[0] = True
    for k in keys:
        ks = k[order]
        new[1:] |= ks[1:] != ks[:-1]
    ids = np.empty(len(r), np.int64)
    ids[order] = np.cumsum(new) - 1
    return ids


def match(sides: np.ndarray, query: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For each query row: a row of ``sides`` with the same nodes (-1 if none), and how many
    rows of ``sides`` have those nodes (1: a boundary side; 2: an internal one)."""
    inv = same_nodes(np.vstack([sides, query]))
    n_keys = inv.max() + 1 if inv.size else 0
    count = np.bincount(inv[: len(sides)], minlength=n_keys)
    row = np.full(n_keys, -1)
    row[inv[: len(sides)]] = np.arange(len(sides))
    q = inv[len(sides):]
    return row[q], count[q]


def boundary_edges(mesh: Mesh) -> np.ndarray:
    """The (k, 2) boundary edges of a 2D mesh, counter-clockwise around the body (outward normal
    (dy, -dx)/L): the cell sides that belong to one cell only. Pressure loads belong here."""
    if mesh.dim != 2:
        raise ValueError(f"boundary_edges is for 2D meshes; this one is {mesh.dim}D "
                         "(see boundary_faces)")
    return _boundary(cell_sides(mesh.cells, 2))


def boundary_faces(mesh: Mesh) -> np.ndarray:
    """The boundary faces of a 3D mesh, (k, 4) quadrilaterals of hex8 or (k, 3) triangles of tet4
    cells, right-hand normal pointing out of the body."""
    if mesh.dim != 3:
        raise ValueError(f"boundary_faces is for 3D meshes; this one is {mesh.dim}D (see boundary_edges)")
    return _boundary(cell_sides(mesh.cells, 3))


def _boundary(sides: np.ndarray) -> np.ndarray:
    ids = same_nodes(sides)
    return sides[np.bincount(ids)[ids] == 1]


def on_boundary(mesh: Mesh, sides: np.ndarray) -> np.ndarray:
    """Boolean mask: which (k, 2) edges (2D) or (k, 4) / (k, 3) faces (3D) lie on the body's boundary."""
    sides = np.asarray(sides, dtype=np.int64)
    if sides.size == 0:
        return np.zeros(len(sides), bool)
    _, count = match(cell_sides(mesh.cells, mesh.dim), sides)
    return count == 1


def side_cells(mesh: Mesh, sides: np.ndarray) -> np.ndarray:
    """The cell of each boundary side (-1 for a side of no cell)."""
    all_sides = cell_sides(mesh.cells, mesh.dim)
    row, _ = match(all_sides, np.asarray(sides, dtype=np.int64))
    per_cell = all_sides.shape[0] // max(mesh.cells.shape[0], 1)
    return np.where(row >= 0, row // per_cell, -1)


def outer_boundary(mesh: Mesh) -> np.ndarray:
    """The boundary sides of the body without the faces of its cohesive cracks: (k, 2) edges
    counter-clockwise (2D) or (k, 4) outward faces (3D). In-situ tractions act here. Of a rank's
    piece of a mesh: the whole body's sides on the piece's cells."""
    if mesh.place is not None:
        return mesh.place.outer
    sides = boundary_edges(mesh) if mesh.dim == 2 else boundary_faces(mesh)
    if not mesh.interfaces.size:
        return sides
    half = mesh.interfaces.shape[1] // 2
    crack = np.vstack([mesh.interfaces[:, :half], mesh.interfaces[:, half:]])
    _, count = match(crack, sides)
    return sides[count == 0]
