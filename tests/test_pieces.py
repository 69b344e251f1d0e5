"""An MPI rank's piece of the mesh (issue 17): rank 0 cuts every rank's share from the whole split
mesh (rockfrac.case.shares, rockfrac.mesh.piece), and a rank then never holds the whole mesh. Checked
on one process: the pieces put back together are the whole mesh (cells, interface cells, node and
side groups, regions, the outer boundary, each once), each rank's cohesive points are the whole
set's (weights, frames, junctions), and a step's ParaView pieces join into the whole grid."""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest

from rockfrac.case.build import build, resolve
from rockfrac.case.schema import parse_case
from rockfrac.case.shares import cut_shares
from rockfrac.elements.interface_points import interface_points
from rockfrac.mesh.interfaces import looped_pairs, tied_nodes
from rockfrac.mesh.partition import partition
from rockfrac.mesh.topology import outer_boundary, same_nodes
from rockfrac.output.fields import step_output
from rockfrac.output.history import Monitor
from rockfrac.output.vtk import join_pieces, piece_of

BRAZILIAN = Path(__file__).resolve().parents[1] / "examples" / "rock_tests" / "brazilian"


def _disc(form: str = "ep") -> dict:
    """The Brazilian disc split along every edge (coarse mesh), a monitor between two groups."""
    case = tomllib.loads((BRAZILIAN / "everywhere.toml").read_text())
    case["mesh"]["file"] = str(BRAZILIAN / "disc_coarse.msh")
    if form == "rp":
        case["cohesive"]["form"] = "rp"
        case["cohesive"].pop("kn", None)
        case["cohesive"].pop("kt", None)
    return case


def _rows(a: np.ndarray) -> set:
    """Rows as a set of node sets (any order within a row)."""
    return {tuple(sorted(r)) for r in np.asarray(a).tolist()}


@pytest.mark.parametrize("n", [2, 3])
def test_the_pieces_put_together_are_the_whole_mesh_each_part_once(n):
    case = resolve(parse_case(_disc(), "disc"), "disc")
    whole, cut = cut_shares(case, "disc", n, lambda mesh: partition(mesh, n))
    shares = list(cut)
    assert len(shares) == n
    cells, interfaces, outer = [], [], []
    sides = {name: [] for name in whole.edge_sets}
    regions = {name: [] for name in whole.regions}
    for r, share in enumerate(shares):
        piece, place = share.mesh, share.mesh.place
        assert place is not None and place.n_nodes == whole.n_nodes and place.n_cells == whole.cells.shape[0]
        ids = place.nodes
        assert np.all(np.diff(ids) > 0) and np.all(np.diff(place.cells) > 0)  # the whole mesh's order kept
        np.testing.assert_array_equal(piece.nodes, whole.nodes[ids])
        np.testing.assert_array_equal(ids[piece.cells], whole.cells[place.cells])
        np.testing.assert_array_equal(ids[piece.interfaces], whole.interfaces[place.interfaces])
        assert np.all(share.partition.cell_part == r)  # a rank's piece: its own cells only
        assert piece.cells.shape[0] < 0.7 * whole.cells.shape[0]
        cells.append(place.cells)
        interfaces.append(place.interfaces[share.partition.interface_part == r])
        outer.append(ids[place.outer])
        for name in sides:
            sides[name].append(ids[piece.edge_sets[name]])
        for name in regions:
            regions[name].append(place.cells[piece.regions[name]])
        for name, nodes in whole.node_sets.items():  # a node group keeps the nodes the piece has
            np.testing.assert_array_equal(ids[piece.node_sets[name]], np.intersect1d(nodes, ids))
            assert place.node_set_sizes[name] == nodes.shape[0]
        np.testing.assert_array_equal(place.bounds, [whole.nodes.min(axis=0), whole.nodes.max(axis=0)])
    for parts, count in ((cells, whole.cells.shape[0]), (interfaces, whole.interfaces.shape[0])):
        np.testing.assert_array_equal(np.sort(np.concatenate(parts)), np.arange(count))  # each once
    every_outer = np.concatenate(outer)
    assert every_outer.shape[0] == outer_boundary(whole).shape[0] and _rows(every_outer) == _rows(outer_boundary(whole))
    for name, parts in sides.items():  # each side of a group on the piece of its cell: once
        joined = np.concatenate(parts)
        assert joined.shape[0] == whole.edge_sets[name].shape[0], name
        assert np.unique(same_nodes(joined)).shape[0] == joined.shape[0]
        assert _rows(joined) == _rows(whole.edge_sets[name])
    for name, parts in regions.items():
        np.testing.assert_array_equal(np.sort(np.concatenate(parts)), np.sort(whole.regions[name]))


@pytest.mark.parametrize("form", ["ep", "rp"])
def test_each_ranks_points_are_the_whole_sets_with_their_weights_and_junctions(form):
    n = 3
    case = resolve(parse_case(_disc(form), "disc"), "disc")
    whole, cut = cut_shares(case, "disc", n, lambda mesh: partition(mesh, n))
    shares = list(cut)
    every = interface_points(whole.nodes, whole.interfaces)  # the one set: every interface cell
    root = tied_nodes(whole)
    junction = np.bincount(root, minlength=whole.n_nodes)[root[every.minus]] >= 3
    on_loops = looped_pairs(every.minus, every.plus, whole.n_nodes)
    assert on_loops.any() and not on_loops.all()
    seen = []
    for r, share in enumerate(shares):
        mine, ids = share.cohesive[0], share.mesh.place.nodes
        p = mine.points
        assert mine.total == every.n
        k = p.index
        seen.append(k)
        np.testing.assert_array_equal(ids[p.minus], every.minus[k])
        np.testing.assert_array_equal(ids[p.plus], every.plus[k])
        np.testing.assert_allclose(p.weight, every.weight[k], rtol=1e-15)  # from every cell of the pair
        np.testing.assert_allclose(p.frame, every.frame[k], rtol=1e-15, atol=1e-15)
        np.testing.assert_array_equal(p.x, every.x[k])
        if form == "rp":
            np.testing.assert_array_equal(mine.junction, junction[k])
            np.testing.assert_array_equal(mine.on_loops, on_loops[k])
            assert mine.owners is None  # each rank's count only: nothing of the set's size
            assert mine.owner_counts is not None and mine.owner_counts.sum() == every.n
            assert mine.owner_counts[r] == p.n
        else:
            assert mine.owners is None and mine.junction is None and mine.owner_counts is None and mine.on_loops is None
        keep = np.zeros(every.n, dtype=bool)
        keep[k] = True
        np.testing.assert_array_equal(ids[p.segments], every.subset(keep).segments)  # its cells, on the piece
    np.testing.assert_array_equal(np.sort(np.concatenate(seen)), np.arange(every.n))


def test_a_monitor_on_a_piece_keeps_the_whole_groups_counts():
    case = resolve(parse_case(_disc(), "disc"), "disc")
    whole, cut = cut_shares(case, "disc", 2, lambda mesh: partition(mesh, 2))
    shares = list(cut)
    nodes = next(v for v in whole.node_sets.values() if v.shape[0] > 2)
    m = Monitor("gap", ["gap"], (nodes, nodes[:1]), np.array([1.0, 0.0]), "")
    for share in shares:
        ids = share.mesh.place.nodes
        on = m.on_piece(ids)
        assert on.count(0) == nodes.shape[0] and on.count(1) == 1  # the means' denominators: the whole's
        np.testing.assert_array_equal(ids[on.nodes[0]], np.intersect1d(nodes, ids))
    assert sum(m.on_piece(s.mesh.place.nodes).nodes[1].shape[0] for s in shares) >= 1


def test_the_pieces_of_a_step_join_into_the_whole_grid():
    built = build(parse_case(_disc(), "disc"))
    u = 1e-6 * np.random.default_rng(0).standard_normal(built.model.n_dofs)
    fields = step_output(built, u)
    rng = np.random.default_rng(1)
    owner = [rng.integers(0, 3, conn.shape[0]) for _, conn in fields.cells]
    pieces = [piece_of(fields, [o == r for o in owner]) for r in range(3)]
    joined = join_pieces(pieces)
    np.testing.assert_array_equal(joined.points, fields.points)
    assert [k for k, _ in joined.cells] == [k for k, _ in fields.cells]
    for (_, a), (_, b) in zip(joined.cells, fields.cells):
        np.testing.assert_array_equal(a, b)
    assert set(joined.point_data) == set(fields.point_data) and set(joined.cell_data) == set(fields.cell_data)
    for name, v in fields.point_data.items():
        np.testing.assert_array_equal(joined.point_data[name], v)
    for name, blocks in fields.cell_data.items():
        for a, b in zip(joined.cell_data[name], blocks):
            np.testing.assert_array_equal(a, b)


def _band(kinematics: str = "elemental", element: str = "quad4") -> dict:
    """An embedded band on 12 x 24 cells with a weak seed (tests/test_crack_tracking.py)."""
    from test_crack_tracking import H, W, band_case

    mesh = {"kind": "block", "element": element, "width": W, "height": H, "nx": 12, "ny": 24,
            "inclusion": [0.0, 0.0067, 0.0034, 0.0167], **({"thickness": 0.01, "nz": 1} if element == "hex8" else {})}
    case = band_case(mesh, {"tracking": "local"})
    if kinematics == "nodal":
        case["embedded"].update(kinematics="nodal", kn=1e10, kt=1e10)
    return case


def _side_neighbours(cells: np.ndarray, dim: int) -> list[set[int]]:
    """Each cell's neighbours across its sides, by brute force (a dict of sorted sides)."""
    from rockfrac.mesh.topology import cell_sides

    sides = cell_sides(cells, dim).reshape(cells.shape[0], -1, 2 if dim == 2 else 4)
    by_side: dict[tuple, list[int]] = {}
    for c in range(cells.shape[0]):
        for side in sides[c].tolist():
            by_side.setdefault(tuple(sorted(side)), []).append(c)
    out: list[set[int]] = [set() for _ in range(cells.shape[0])]
    for held in by_side.values():
        for c in held:
            out[c].update(o for o in held if o != c)
    return out


@pytest.mark.parametrize("n, element", [(2, "quad4"), (3, "quad4"), (2, "hex8")])
def test_an_embedded_cases_piece_is_its_own_cells_and_their_neighbours(n, element):
    """With embedded cracks a rank's piece holds its own cells and every cell across one of their
    sides (edges; faces of hexahedra), no other, and each cell's place in its material's serial
    order; with nodal cracks every cell sharing a node with one of its own, and the nodes the
    enrichment numbers with their ranks."""
    case = resolve(parse_case(_band(element=element), "band"), "band")
    part_of = {}
    whole, cut = cut_shares(case, "band", n, lambda mesh: part_of.setdefault("p", partition(mesh, n)))
    neighbours = _side_neighbours(whole.cells, whole.dim)
    serial = np.zeros(whole.cells.shape[0], dtype=np.int64)
    for region in ("bulk", "weak"):
        serial[whole.regions[region]] = np.arange(whole.regions[region].size)
    part = part_of["p"]
    for r, share in enumerate(cut):
        own = set(np.flatnonzero(part.cell_part == r).tolist())
        expected = own | {o for c in own for o in neighbours[c]}
        assert set(share.mesh.place.cells.tolist()) == expected
        assert len(expected) < 0.75 * whole.cells.shape[0]
        np.testing.assert_array_equal(share.cell_serial, serial[share.mesh.place.cells])
        assert share.enrichment is None
    if element != "quad4":
        return
    nodal = resolve(parse_case(_band("nodal"), "band"), "band")
    part_of.clear()
    whole, cut = cut_shares(nodal, "band", n, lambda mesh: part_of.setdefault("p", partition(mesh, n)))
    part = part_of["p"]
    for r, share in enumerate(cut):
        own = np.flatnonzero(part.cell_part == r)
        at = set(whole.cells[own].ravel().tolist())
        expected = {c for c in range(whole.cells.shape[0]) if at & set(whole.cells[c].tolist())}
        assert set(share.mesh.place.cells.tolist()) == expected
        assert len(expected) < 0.75 * whole.cells.shape[0]
        nodes, ranks = share.enrichment
        np.testing.assert_array_equal(nodes, np.arange(whole.n_nodes))  # the band's rock is all EDE cells
        np.testing.assert_array_equal(ranks, part.node_part)
