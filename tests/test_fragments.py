"""Fragments of a mesh with cohesive surfaces (rockfrac.output.fragments): a body is cut into pieces
only where a crack of separated pairs closes round them; a crack that stops inside the mesh, or one
pair that still holds, leaves it whole."""

import numpy as np
import pytest

from rockfrac.mesh import Mesh
from rockfrac.mesh.interfaces import all_edges, insert_interfaces
from rockfrac.mesh.interfaces_3d import all_faces, insert_faces
from rockfrac.output.fragments import Fragments
from test_interfaces import grid


def split_grid(n: int, tri: bool = False) -> Mesh:
    """The unit square of n x n quads (or 2 n^2 triangles), a surface on every internal edge."""
    m = grid(n, n, tri=tri)
    return insert_interfaces(m, all_edges(m))


def pairs_where(mesh: Mesh, keep) -> np.ndarray:
    """The (minus, plus) pairs of the interface cells whose minus side's midpoint passes ``keep``."""
    half = mesh.interfaces.shape[1] // 2
    mid = mesh.nodes[mesh.interfaces[:, :half]].mean(axis=1)
    hit = mesh.interfaces[keep(mid)]
    return np.concatenate([np.stack([hit[:, j], hit[:, half + j]], axis=1) for j in range(half)])


@pytest.mark.parametrize("tri", [False, True])
def test_an_intact_mesh_is_one_fragment_and_every_pair_broken_makes_every_cell_one(tri):
    m = split_grid(4, tri)
    f = Fragments(m)
    whole = f.pieces(np.zeros((0, 2), dtype=np.int64))
    assert whole.count == 1 and whole.size[0] == pytest.approx(1.0, rel=1e-12)
    assert whole.centroid[0] == pytest.approx([0.5, 0.5], rel=1e-12)
    every = f.pieces(pairs_where(m, lambda x: np.ones(x.shape[0], dtype=bool)))
    assert every.count == m.cells.shape[0]
    assert np.allclose(every.size, 1.0 / m.cells.shape[0], rtol=1e-12) and np.all(every.cells == 1)


def test_a_crack_across_cuts_two_pieces_and_one_stopping_inside_or_held_at_one_pair_does_not():
    m = split_grid(4)
    f = Fragments(m)
    vertical = lambda x: np.isclose(x[:, 0], 0.25) & (np.abs(x[:, 1] - 0.5) < 1.0)  # noqa: E731
    through = pairs_where(m, vertical)  # the line x = 0.25 from the bottom to the top
    two = f.pieces(through)
    assert two.count == 2
    assert two.size == pytest.approx([0.75, 0.25], rel=1e-12)  # the largest first
    assert two.centroid[0] == pytest.approx([0.625, 0.5], rel=1e-12)
    assert two.centroid[1] == pytest.approx([0.125, 0.5], rel=1e-12)
    assert np.all(two.cell_fragment[np.isclose(m.nodes[m.cells].mean(axis=1)[:, 0], 0.125)] == 1)
    stops = pairs_where(m, lambda x: np.isclose(x[:, 0], 0.25) & (x[:, 1] < 0.7))  # three of four edges
    assert f.pieces(stops).count == 1
    middle = np.isclose(m.nodes[through[:, 0], 1], 0.5)  # the pair at (0.25, 0.5), in both of its cells
    assert middle.sum() == 2
    held = through[~middle]  # every pair of the line but one
    assert f.pieces(held).count == 1
    assert f.pieces(held[:, ::-1]).count == 1  # the pairs' nodes in either order
    assert f.pieces(through[:, ::-1]).count == 2


def test_a_block_cut_by_two_crossing_cracks_falls_into_four():
    m = split_grid(4, tri=True)
    f = Fragments(m)
    cross = pairs_where(m, lambda x: np.isclose(x[:, 0], 0.5) | np.isclose(x[:, 1], 0.5))
    four = f.pieces(cross)
    assert four.count == 4 and four.size == pytest.approx([0.25] * 4, rel=1e-12)
    assert sorted(map(tuple, np.round(four.centroid, 12))) == [(0.25, 0.25), (0.25, 0.75), (0.75, 0.25), (0.75, 0.75)]


def test_a_hexahedral_box_cut_by_a_plane_falls_into_two():
    n = 3
    x, y, z = np.meshgrid(*(np.linspace(0.0, 1.0, n + 1),) * 3, indexing="ij")
    ids = np.arange((n + 1) ** 3).reshape(n + 1, n + 1, n + 1)
    i, j, k = (a.ravel() for a in np.meshgrid(*(np.arange(n),) * 3, indexing="ij"))
    cells = np.stack([ids[i, j, k], ids[i + 1, j, k], ids[i + 1, j + 1, k], ids[i, j + 1, k],
                      ids[i, j, k + 1], ids[i + 1, j, k + 1], ids[i + 1, j + 1, k + 1], ids[i, j + 1, k + 1]], axis=1)
    m = insert_faces(Mesh(np.column_stack([x.ravel(), y.ravel(), z.ravel()]), cells, "hex8"),
                     all_faces(Mesh(np.column_stack([x.ravel(), y.ravel(), z.ravel()]), cells, "hex8")))
    f = Fragments(m)
    assert f.pieces(np.zeros((0, 2), dtype=np.int64)).count == 1
    plane = f.pieces(pairs_where(m, lambda c: np.isclose(c[:, 2], 1.0 / 3.0)))
    assert plane.count == 2 and plane.size == pytest.approx([2.0 / 3.0, 1.0 / 3.0], rel=1e-12)
    assert plane.centroid[1] == pytest.approx([0.5, 0.5, 1.0 / 6.0], rel=1e-12)
