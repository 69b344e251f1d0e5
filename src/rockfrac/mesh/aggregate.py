"""A 3D grain aggregate: a box of tetrahedra whose cells are grouped into Voronoi grains.

:func:`grain_box` splits an n_x x n_y x n_z grid of hexahedra into six tetrahedra each (the
Freudenthal-Kuhn split along the main diagonal, conforming between neighbours) and gives every
tetrahedron to the grain of the seed nearest its centroid: a Voronoi tessellation of random seeds
resolved on the mesh (grain boundaries follow the cells' faces, so they are stepped at the scale of
a cell, not planar). Regions ``grain_1`` .. ``grain_N``; faces left/right (x), front/back (y),
bottom/top (z); points ``origin`` (0, 0, 0), ``x_axis`` (L_x, 0, 0). Cohesive surfaces on the grain
boundaries: ``[cohesive] where = "boundaries"``.
"""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from rockfrac.mesh.mesh import Mesh
from rockfrac.mesh.rock_tests import write_tets
from rockfrac.mesh.topology import boundary_faces


def kuhn_tets(n: tuple[int, int, int], size: tuple[float, float, float]) -> tuple[np.ndarray, np.ndarray]:
    """Nodes ((n_x+1)(n_y+1)(n_z+1), 3) [m] and right-handed tetrahedra (6 n_x n_y n_z, 4) of a box."""
    nx, ny, nz = n
    axes = [np.linspace(0.0, size[i], n[i] + 1) for i in range(3)]
    x, y, z = np.meshgrid(*axes, indexing="ij")
    nodes = np.column_stack([x.ravel(), y.ravel(), z.ravel()])
    stride = np.array([(ny + 1) * (nz + 1), nz + 1, 1])
    i, j, k = (a.ravel() for a in np.meshgrid(np.arange(nx), np.arange(ny), np.arange(nz), indexing="ij"))
    base = i * stride[0] + j * stride[1] + k * stride[2]
    tets = []
    for perm in itertools.permutations(range(3)):  # the path (0,0,0) -> +e_a -> +e_b -> +e_c
        corner, path = np.zeros(3, dtype=np.int64), [base]
        for a in perm:
            corner[a] += 1
            path.append(base + int(corner @ stride))
        tets.append(np.stack(path, axis=1))
    cells = np.vstack(tets)
    xc = nodes[cells]
    vol = np.einsum("ki,ki->k", np.cross(xc[:, 1] - xc[:, 0], xc[:, 2] - xc[:, 0]), xc[:, 3] - xc[:, 0])
    cells[vol < 0] = cells[vol < 0][:, [0, 2, 1, 3]]
    return nodes, cells


def grain_box(path: str | Path, size: tuple[float, float, float] = (0.05, 0.05, 0.1),
              cells: tuple[int, int, int] = (8, 8, 16), n_grains: int = 20, seed: int = 0) -> Path:
    """Write the aggregate as a Gmsh .msh file (see the module); returns the path."""
    if n_grains < 1:
        raise ValueError(f"n_grains must be >= 1, got {n_grains}")
    nodes, tets = kuhn_tets(cells, size)
    seeds = np.random.default_rng(seed).uniform(0.0, 1.0, (n_grains, 3)) * np.asarray(size)
    grain = cKDTree(seeds).query(nodes[tets].mean(axis=1))[1]
    regions = {f"grain_{g + 1}": np.flatnonzero(grain == g) for g in range(n_grains) if np.any(grain == g)}
    mesh = Mesh(nodes=nodes, cells=tets, cell_type="tet4")
    outer = boundary_faces(mesh)
    centre = nodes[outer].mean(axis=1)
    faces = {}
    for name, axis, at in (("left", 0, 0.0), ("right", 0, size[0]), ("front", 1, 0.0), ("back", 1, size[1]),
                           ("bottom", 2, 0.0), ("top", 2, size[2])):
        faces[name] = outer[np.isclose(centre[:, axis], at, atol=1e-9 * max(size))]
    points = {"origin": 0, "x_axis": int(np.argmin(np.linalg.norm(nodes - [size[0], 0.0, 0.0], axis=1)))}
    return write_tets(path, nodes, tets, faces, points, regions)
