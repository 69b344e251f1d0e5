"""Generated heterogeneous specimens: grains in a matrix (Gmsh), a block with a weak inclusion."""

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from rockfrac.mesh.gmsh_io import boundary_edges, read_mesh
from rockfrac.mesh.grains import block_with_inclusion, grain_specimen, place_grains, write_grain_msh

W, H = 0.04, 0.08
SMALL = {"width": W, "height": H, "n_grains": 8, "radius": (0.004, 0.006), "seed": 3,
         "element_size": 0.003}
SIDES = {"bottom": (0.0, -1.0), "right": (1.0, 0.0), "top": (0.0, 1.0), "left": (-1.0, 0.0)}


def areas(mesh):
    x = mesh.nodes[mesh.cells]
    x1 = np.roll(x, -1, axis=1)
    return 0.5 * (x[..., 0] * x1[..., 1] - x1[..., 0] * x[..., 1]).sum(axis=1)


def edge_neighbours(mesh):
    """(k, 2) pairs of cells sharing an edge."""
    nv = mesh.cells.shape[1]
    e = np.stack([mesh.cells, np.roll(mesh.cells, -1, axis=1)], axis=-1).reshape(-1, 2)
    e = np.sort(e, axis=1)
    _, inv, count = np.unique(e, axis=0, return_inverse=True, return_counts=True)
    inv = inv.ravel()
    order = np.argsort(inv, kind="stable")
    shared = order[count[inv[order]] == 2].reshape(-1, 2)
    return shared // nv


@pytest.fixture(scope="module", params=["quad4", "tri3"])
def grains(request):
    return request.param, grain_specimen(**SMALL, element=request.param)


def test_cells_and_regions(grains):
    element, mesh = grains
    assert mesh.cell_type == element and mesh.cells.shape[1] == (4 if element == "quad4" else 3)
    assert mesh.check() == []
    g, m = mesh.regions["grains"], mesh.regions["matrix"]
    assert set(mesh.regions) == {"grains", "matrix"} and len(g) > 0 and len(m) > 0
    assert np.array_equal(np.sort(np.concatenate([g, m])), np.arange(len(mesh.cells)))
    a = areas(mesh)
    assert np.all(a > 0) and a.sum() == pytest.approx(W * H, rel=1e-12)


def test_grain_area_and_separation(grains):
    _, mesh = grains
    circles = place_grains(W, H, SMALL["n_grains"], SMALL["radius"], seed=SMALL["seed"])
    a = areas(mesh)
    g = mesh.regions["grains"]
    assert a[g].sum() == pytest.approx(np.pi * np.sum(circles[:, 2] ** 2), rel=0.02)
    # the grains touch no other grain: their cells form n_grains separate patches, one per circle
    pairs = edge_neighbours(mesh)
    is_grain = np.isin(np.arange(len(mesh.cells)), g)
    inner = pairs[is_grain[pairs].all(axis=1)]
    n = len(mesh.cells)
    graph = sp.coo_matrix((np.ones(len(inner)), (inner[:, 0], inner[:, 1])), shape=(n, n))
    _, label = connected_components(graph, directed=False)
    patches = np.unique(label[g])
    assert len(patches) == SMALL["n_grains"]
    centroid = mesh.nodes[mesh.cells].mean(axis=1)
    for p in patches:
        cells = g[label[g] == p]
        c = (a[cells, None] * centroid[cells]).sum(axis=0) / a[cells].sum()
        i = np.argmin(np.linalg.norm(circles[:, :2] - c, axis=1))
        assert a[cells].sum() == pytest.approx(np.pi * circles[i, 2] ** 2, rel=0.02)
    # across every grain boundary the neighbour is a matrix cell
    mixed = pairs[is_grain[pairs].sum(axis=1) == 1]
    assert len(mixed) > 0 and np.isin(mixed[~is_grain[mixed]], mesh.regions["matrix"]).all()


def test_boundary_groups(grains):
    _, mesh = grains
    total = 0.0
    for name, normal in SIDES.items():
        d = mesh.nodes[mesh.edge_sets[name][:, 1]] - mesh.nodes[mesh.edge_sets[name][:, 0]]
        length = np.linalg.norm(d, axis=1)
        assert np.allclose(np.column_stack([d[:, 1], -d[:, 0]]) / length[:, None], normal)
        total += length.sum()
        assert np.array_equal(np.unique(mesh.edge_sets[name]), mesh.node_sets[name])
    assert total == pytest.approx(2 * (W + H))
    all_sides = {tuple(e) for n in SIDES for e in mesh.edge_sets[n]}
    assert all_sides == {tuple(e) for e in boundary_edges(mesh)}
    assert np.allclose(mesh.nodes[mesh.node_sets["bottom_left"]], [[0.0, 0.0]])


def test_deterministic_for_a_seed_and_written_file_equal(tmp_path):
    a, again = grain_specimen(**SMALL), grain_specimen(**SMALL)
    assert np.array_equal(a.cells, again.cells) and np.array_equal(a.nodes, again.nodes)
    b = read_mesh(write_grain_msh(tmp_path / "grains.msh", **SMALL))
    assert np.array_equal(a.cells, b.cells) and np.allclose(a.nodes, b.nodes, rtol=0, atol=1e-15)
    assert all(np.array_equal(a.regions[k], b.regions[k]) for k in a.regions)
    assert all(np.array_equal(a.edge_sets[k], b.edge_sets[k]) for k in a.edge_sets)
    c = place_grains(W, H, SMALL["n_grains"], SMALL["radius"], seed=SMALL["seed"] + 1)
    same = place_grains(W, H, SMALL["n_grains"], SMALL["radius"], seed=SMALL["seed"])
    assert not np.allclose(c, same)


def test_placement_keeps_gaps_and_fails_clearly():
    gap = 0.001
    c = place_grains(W, H, 30, (0.002, 0.004), min_gap=gap, seed=0)
    d = np.linalg.norm(c[:, None, :2] - c[None, :, :2], axis=2) - c[:, None, 2] - c[None, :, 2]
    assert d[~np.eye(len(c), dtype=bool)].min() >= gap
    assert (c[:, 0] - c[:, 2]).min() >= gap and (c[:, 0] + c[:, 2]).max() <= W - gap
    assert (c[:, 1] - c[:, 2]).min() >= gap and (c[:, 1] + c[:, 2]).max() <= H - gap
    with pytest.raises(ValueError, match=r"placed only \d+ of 500 grains"):
        place_grains(W, H, 500, (0.002, 0.004), attempts=512)


@pytest.mark.parametrize("element", ["quad4", "tri3"])
def test_block_with_inclusion(element):
    box = (0.0, 0.03, 0.04, 0.05)
    mesh = block_with_inclusion(W, H, 4, 8, box, element=element)
    assert mesh.check() == [] and mesh.cell_type == element
    c = mesh.nodes[mesh.cells].mean(axis=1)
    weak, bulk = mesh.regions["weak"], mesh.regions["bulk"]
    inside = (c[:, 1] >= 0.03) & (c[:, 1] <= 0.05)
    assert np.array_equal(weak, np.flatnonzero(inside))
    assert np.array_equal(bulk, np.flatnonzero(~inside))
    assert len(weak) == (8 if element == "quad4" else 16)  # two rows of 4 quads
    length = sum(np.linalg.norm(np.diff(mesh.nodes[mesh.edge_sets[n]], axis=1), axis=2).sum()
                 for n in SIDES)
    assert length == pytest.approx(2 * (W + H))
    d = np.diff(mesh.nodes[mesh.edge_sets["left"]], axis=1)[:, 0]
    assert np.all(d[:, 1] < 0)  # counter-clockwise: down the left side
    assert np.array_equal(mesh.node_sets["bottom_left"], [0])
    plain = block_with_inclusion(W, H, 2, 2)
    assert set(plain.regions) == {"bulk"} and len(plain.regions["bulk"]) == 4
    with pytest.raises(ValueError, match="holds no cell centroid"):
        block_with_inclusion(W, H, 2, 2, (0.0, 0.0, 0.001, 0.001))


def test_points_per_circle_refines_the_grains_through_the_case():
    """[mesh] points_per_circle (kind = 'grains'): near the grains the circles' nodes, not element_size,
    set the elements, so a refinement doubles both; the meshed grains' area then approaches the circles'
    (the polygon's deficit falls like 1/n^2) and each grain's boundary has at least that many nodes."""
    from rockfrac.case.build_mesh import make_mesh
    from rockfrac.case.schema import parse_case

    def mesh_of(points):
        extra = {} if points is None else {"points_per_circle": points}
        case = parse_case({"mesh": dict(kind="grains", width=W, height=H, n_grains=8, radius_min=0.004,
                                        radius_max=0.006, seed=3, element_size=0.003, **extra),
                           "bulk": {"E": 1e7, "nu": 0.2},
                           "loading": {"confinement": 0.0, "axial_steps": 1, "axial_displacement": -1e-4}})
        assert case.mesh.resolved().points_per_circle == (24 if points is None else points)
        return make_mesh(case)

    circles = place_grains(W, H, 8, (0.004, 0.006), seed=3)
    exact = np.pi * np.sum(circles[:, 2] ** 2)
    deficit, meshes = {}, {}
    for points in (None, 48):
        mesh = meshes[points] = mesh_of(points)
        a = areas(mesh)
        deficit[points] = 1.0 - a[mesh.regions["grains"]].sum() / exact
        # every grain's circle: the nodes of the grain cells' outer edges within 1e-6 m of it
        x = mesh.nodes[np.unique(mesh.cells[mesh.regions["grains"]])]
        for cx, cy, r in circles:
            on = np.abs(np.hypot(x[:, 0] - cx, x[:, 1] - cy) - r) < 1e-6
            assert on.sum() >= (24 if points is None else 48)
    assert deficit[None] > 0 and 0 < deficit[48] < 0.4 * deficit[None]
    assert meshes[48].cells.shape[0] > 1.5 * meshes[None].cells.shape[0]
