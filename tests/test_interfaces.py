"""Cohesive-surface insertion: node splitting at crack tips, boundaries and junctions, interface
orientation, node/edge sets carried over, and an elastic solve showing that the split mesh with
its interfaces tied exactly reproduces the unsplit solution."""

import numpy as np
import pytest

from rockfrac.elements.solid import ElasticSolid
from rockfrac.fem.loads import edge_pressure
from rockfrac.fem.reference import ELEMENTS
from rockfrac.mesh import Mesh, cracked_specimen
from rockfrac.mesh.interfaces import (
    all_edges,
    edges_between,
    edges_on,
    edges_within,
    insert_interfaces,
    internal_edges,
    looped_pairs,
    minus_side,
    tied_nodes,
)
from rockfrac.model import Model
from rockfrac.solve.linear import SuperLU
from rockfrac.solve.newton import Loads, NewtonOptions, newton_step


def grid(nx: int, ny: int, tri: bool = False, size: float = 1.0) -> Mesh:
    """Unit square of nx x ny quads (node (i, j) is j (nx + 1) + i), or each cut in two tri3."""
    x, y = np.meshgrid(np.linspace(0, size, nx + 1), np.linspace(0, size, ny + 1))
    ids = np.arange((nx + 1) * (ny + 1)).reshape(ny + 1, nx + 1)
    q = np.stack([ids[:-1, :-1], ids[:-1, 1:], ids[1:, 1:], ids[1:, :-1]], axis=-1).reshape(-1, 4)
    cells = np.vstack([q[:, [0, 1, 2]], q[:, [0, 2, 3]]]) if tri else q
    return Mesh(np.column_stack([x.ravel(), y.ravel()]), cells, "tri3" if tri else "quad4")


def node(i: int, j: int, nx: int = 4) -> int:
    return j * (nx + 1) + i


def chain(*points, nx: int = 4) -> np.ndarray:
    """Polyline of grid nodes through the given (i, j) points, one grid step at a time."""
    out = [node(*points[0], nx)]
    for (i0, j0), (i1, j1) in zip(points[:-1], points[1:]):
        steps = max(abs(i1 - i0), abs(j1 - j0))
        for s in range(1, steps + 1):
            out.append(node(i0 + s * np.sign(i1 - i0), j0 + s * np.sign(j1 - j0), nx))
    return np.array(out)


def directed_cell_edges(mesh: Mesh) -> set:
    c = mesh.cells
    return set(zip(c.ravel().tolist(), np.roll(c, -1, axis=1).ravel().tolist()))


def check_split(old: Mesh, new: Mesh, selected, minus_cells=None):
    """Invariants of every split; returns the added interface cells."""
    assert new.check() == []
    ie = internal_edges(old)
    sel = np.flatnonzero(selected) if np.asarray(selected).dtype == bool else np.asarray(selected)
    added = new.interfaces[old.interfaces.shape[0]:]
    assert added.shape == (sel.size, 4)  # exactly one interface cell per selected edge
    np.testing.assert_array_equal(new.nodes[new.cells], old.nodes[old.cells])  # same geometry
    np.testing.assert_array_equal(new.nodes[: old.n_nodes], old.nodes)
    minus = ie.cells[sel, 0] if minus_cells is None else np.asarray(minus_cells)
    plus = np.where(minus == ie.cells[sel, 0], ie.cells[sel, 1], ie.cells[sel, 0])
    xm0, xm1 = new.nodes[added[:, 0]], new.nodes[added[:, 1]]
    t = xm1 - xm0
    n = np.stack([-t[:, 1], t[:, 0]], axis=1)
    mid = 0.5 * (xm0 + xm1)
    centroid = new.nodes[new.cells].mean(axis=1)
    assert np.all(np.einsum("ki,ki->k", n, centroid[plus] - mid) > 0)  # n points into the plus cell
    assert np.all(np.einsum("ki,ki->k", n, centroid[minus] - mid) < 0)
    for k in range(sel.size):  # minus nodes from the minus cell, plus nodes from the plus cell
        assert set(added[k, :2]) <= set(new.cells[minus[k]])
        assert set(added[k, 2:]) <= set(new.cells[plus[k]])
    # orientation from connectivity: the minus cell holds m1 -> m0, the plus cell p0 -> p1
    directed = directed_cell_edges(new)
    for m0, m1, p0, p1 in new.interfaces:
        assert (m1, m0) in directed and (p0, p1) in directed
    return added


def copies_at(mesh: Mesh, xy) -> int:
    return int(np.sum(np.all(np.isclose(mesh.nodes, xy), axis=1)))


def test_internal_edges_of_a_grid():
    for tri, expected in ((False, 2 * 4 * 3), (True, 2 * 4 * 3 + 16)):
        m = grid(4, 4, tri)
        ie = internal_edges(m)
        assert ie.edges.shape == ie.cells.shape == ie.local.shape == (expected, 2)
        nv = m.cells.shape[1]
        for e, c, l in zip(ie.edges, ie.cells, ie.local):
            assert tuple(e) == (m.cells[c[0], l[0]], m.cells[c[0], (l[0] + 1) % nv])
            assert set(e) == {m.cells[c[1], l[1]], m.cells[c[1], (l[1] + 1) % nv]}
            assert c[0] < c[1]


def test_straight_crack_through_the_mesh_splits_boundary_nodes():
    m = grid(4, 4)
    sel = edges_on(m, chain((0, 2), (4, 2)))
    assert sel.sum() == 4
    new = insert_interfaces(m, sel)
    added = check_split(m, new, sel)
    assert new.n_nodes == 25 + 5
    for i in range(5):
        assert copies_at(new, (0.25 * i, 0.5)) == 2
    t = new.nodes[added[:, 1]] - new.nodes[added[:, 0]]
    np.testing.assert_allclose(t, np.tile([0.25, 0.0], (4, 1)))  # lower cells are minus: t = +x
    assert not np.any(added[:, :2] == added[:, 2:])
    # the two halves share no node any more
    below, above = np.arange(8), np.arange(8, 16)
    assert not set(new.cells[below].ravel()) & set(new.cells[above].ravel())


def test_crack_ending_inside_keeps_its_tip_node():
    m = grid(4, 4)
    sel = edges_on(m, chain((0, 2), (2, 2)))
    new = insert_interfaces(m, sel)
    added = check_split(m, new, sel)
    assert new.n_nodes == 25 + 2  # (0, .5) and (.25, .5) split; the tip (.5, .5) not
    assert copies_at(new, (0.5, 0.5)) == 1
    tip = node(2, 2)
    assert np.sum(added[:, 1] == tip) == 1 and np.sum(added[:, 3] == tip) == 1


@pytest.mark.parametrize("tri", [False, True])
def test_l_shaped_crack(tri):
    m = grid(4, 4, tri)
    sel = edges_on(m, chain((0, 2), (2, 2), (2, 4)))
    assert sel.sum() == 4
    new = insert_interfaces(m, sel)
    check_split(m, new, sel)
    assert new.n_nodes == 25 + 5  # the corner node has two fans: one copy like the others
    for xy in [(0, .5), (.25, .5), (.5, .5), (.5, .75), (.5, 1)]:
        assert copies_at(new, xy) == 2


@pytest.mark.parametrize("arms,copies", [([(0, 2), (4, 2), (2, 4)], 3),
                                         ([(0, 2), (4, 2), (2, 4), (2, 0)], 4)])
def test_triple_junction_and_cross(arms, copies):
    """Selected edges from the centre node towards each arm's end, one grid step long."""
    m = grid(4, 4)
    centre = node(2, 2)
    pairs = [[centre, node(2 + np.sign(i - 2), 2 + np.sign(j - 2))] for i, j in arms]
    sel = edges_on(m, np.array(pairs))
    new = insert_interfaces(m, sel)
    check_split(m, new, sel)
    assert new.n_nodes == 25 + copies - 1  # the arms' far ends are tips
    assert copies_at(new, (0.5, 0.5)) == copies
    # cells of different fans around the centre hold different copies of it
    around = np.flatnonzero(np.isin(m.cells, centre).any(axis=1))
    held = {c: set(new.cells[c]) & set(np.flatnonzero(np.all(new.nodes == 0.5, axis=1)))
            for c in around}
    assert all(len(h) == 1 for h in held.values())
    assert len(set().union(*held.values())) == copies


@pytest.mark.parametrize("tri", [False, True])
def test_all_edges_disconnect_every_cell(tri):
    m = grid(3, 3, tri)
    new = insert_interfaces(m, all_edges(m))
    check_split(m, new, all_edges(m))
    assert new.n_nodes == m.cells.size  # every node: as many copies as incident cells
    assert np.unique(new.cells).size == new.cells.size  # no two cells share a node


def test_every_edge_within_a_block():
    m = grid(5, 5)
    ij = np.array([(c % 5, c // 5) for c in range(25)])
    m.regions["block"] = np.flatnonzero((ij >= 1).all(axis=1) & (ij <= 3).all(axis=1))  # 3 x 3
    sel = edges_within(m, "block")
    assert sel.sum() == 12
    new = insert_interfaces(m, sel)
    check_split(m, new, sel)
    assert new.n_nodes == 36 + 4 * 3  # the block's 4 interior nodes x 4 fans; its rim is intact
    block_nodes = np.unique(new.cells[m.regions["block"]])
    x = new.nodes[block_nodes]
    interior = block_nodes[np.all((x > 0.2 + 1e-12) & (x < 0.8 - 1e-12), axis=1)]
    assert len(interior) == 16
    np.testing.assert_array_equal(new.regions["block"], m.regions["block"])


def test_edges_between_regions_and_minus_side():
    m = grid(4, 4)
    left = np.flatnonzero(m.nodes[m.cells].mean(axis=1)[:, 0] < 0.5)
    m.regions = {"left": left, "right": np.setdiff1d(np.arange(16), left)}
    sel = edges_between(m, "left", "right")
    assert sel.sum() == 4
    for a, b, nx_sign in (("left", "right", 1.0), ("right", "left", -1.0)):
        minus = minus_side(m, sel, a)
        assert set(minus) <= set(m.regions[a])
        new = insert_interfaces(m, sel, minus)
        added = check_split(m, new, sel, minus)
        assert new.n_nodes == 30
        t = new.nodes[added[:, 1]] - new.nodes[added[:, 0]]
        np.testing.assert_allclose(np.stack([-t[:, 1], t[:, 0]], axis=1) / 0.25,
                                   np.tile([nx_sign, 0.0], (4, 1)), atol=1e-14)
    with pytest.raises(ValueError, match="not one of the two cells"):
        insert_interfaces(m, sel, np.zeros(4, dtype=int) + 15)


def test_node_and_edge_sets_follow_their_cells():
    m = cracked_specimen(1.0, 1.0, nx=4, ny=4, crack=False)
    sel = edges_on(m, chain((0, 2), (4, 2)))
    new = insert_interfaces(m, sel)
    check_split(m, new, sel)
    for name in ("left", "right"):
        assert new.node_sets[name].size == m.node_sets[name].size + 1
        ys = np.sort(new.nodes[new.node_sets[name], 1])
        np.testing.assert_allclose(ys, [0, .25, .5, .5, .75, 1])
    np.testing.assert_array_equal(new.node_sets["bottom"], m.node_sets["bottom"])
    directed = directed_cell_edges(new)
    for name, edges in m.edge_sets.items():
        moved = new.edge_sets[name]
        assert moved.shape == edges.shape
        np.testing.assert_array_equal(new.nodes[moved], m.nodes[edges])  # same length, direction
        assert all((a, b) in directed for a, b in moved)  # still counter-clockwise on its cell
    f_old, f_new = np.zeros(2 * m.n_nodes), np.zeros(2 * new.n_nodes)
    edge_pressure(m.nodes, m.edge_sets["left"], 1.0, f_old)
    edge_pressure(new.nodes, new.edge_sets["left"], 1.0, f_new)
    assert f_new[0::2].sum() == pytest.approx(f_old[0::2].sum()) == pytest.approx(1.0)
    crack_left = np.flatnonzero(np.all(np.isclose(new.nodes, [0, .5]), axis=1))
    assert f_new[2 * crack_left].min() > 0  # both copies carry their own half edge


def test_existing_interfaces_follow_a_new_split():
    """A vertical crack in the specimen's lower block reaching its existing crack."""
    m = cracked_specimen(0.04, 0.08, angle=0.3, nx=2, ny=2)
    ie = internal_edges(m)
    vertical = np.isclose(m.nodes[ie.edges, 0], 0.02).all(axis=1)
    sel = vertical & (ie.cells < 4).all(axis=1)  # the lower block's cells are 0..3
    assert sel.sum() == 2
    new = insert_interfaces(m, sel)
    check_split(m, new, sel)
    assert new.interfaces.shape[0] == 2 + 2
    assert new.n_nodes == m.n_nodes + 3  # (x_mid, 0), the centre, and the old crack's minus node
    assert new.interfaces[1, 0] != m.interfaces[1, 0]  # right of the cut: follows its copy


def test_large_grid_is_vectorized():
    m = grid(60, 60, tri=True)
    new = insert_interfaces(m, all_edges(m))
    assert new.n_nodes == m.cells.size and new.check() == []
    assert new.interfaces.shape[0] == all_edges(m).size


def solve(mesh: Mesh, rep: np.ndarray) -> np.ndarray:
    """Elastic solve: bottom held vertically (bottom-left corner also horizontally), top pushed
    down, left side under pressure. rep: node -> the node whose dofs it uses (identity: nothing
    tied). Returns every node's displacement (n_nodes, 2)."""
    solid = ElasticSolid(mesh.nodes, rep[mesh.cells], ELEMENTS[mesh.cell_type], 1.5e7, 0.3)
    d = np.full(2 * mesh.n_nodes, np.nan)
    d[2 * rep[mesh.node_sets["bottom"]] + 1] = 0.0
    d[2 * rep[mesh.node_sets["bottom_left"]]] = 0.0
    d[2 * rep[mesh.node_sets["top"]] + 1] = -1e-4
    unused = np.setdiff1d(np.arange(mesh.n_nodes), rep)  # copies: their dofs live elsewhere
    d[2 * unused], d[2 * unused + 1] = 0.0, 0.0
    dirichlet = np.flatnonzero(~np.isnan(d))
    f = np.zeros(2 * mesh.n_nodes)
    edge_pressure(mesh.nodes, rep[mesh.edge_sets["left"]], 2e3, f)
    model = Model(mesh.n_nodes, [solid], dirichlet)
    zero = np.zeros(model.n_dofs)
    res = newton_step(model, zero, 0.0, 1.0, Loads(zero[dirichlet], d[dirichlet], zero, f),
                      SuperLU(), NewtonOptions())
    assert res.converged
    return res.u.reshape(-1, 2)[rep]  # every node's displacement


@pytest.mark.parametrize("tri", [False, True])
def test_tied_split_mesh_reproduces_the_unsplit_solution(tri):
    """A triple junction and cracks through three sides; the split dofs are mapped back onto one
    dof through the interface node pairs (tied_nodes)."""
    m = cracked_specimen(1.0, 1.0, nx=4, ny=4, crack=False)
    rng = np.random.default_rng(3)
    inner = np.all((m.nodes > 0.01) & (m.nodes < 0.99), axis=1)
    m.nodes[inner] += rng.uniform(-0.06, 0.06, (inner.sum(), 2))
    if tri:
        q = m.cells
        m = Mesh(m.nodes, np.vstack([q[:, [0, 1, 2]], q[:, [0, 2, 3]]]), "tri3",
                 node_sets=m.node_sets, edge_sets=m.edge_sets)
    sel = edges_on(m, chain((0, 2), (2, 2), (2, 4))) | edges_on(m, chain((2, 2), (4, 2)))
    if tri:
        sel |= all_edges(m) & (np.arange(sel.size) % 3 == 0)
    split = insert_interfaces(m, sel)
    assert split.n_nodes > m.n_nodes

    u_whole = solve(m, np.arange(m.n_nodes))
    rep = tied_nodes(split)
    np.testing.assert_array_equal(split.nodes, m.nodes[rep])  # each copy tied to its original
    u_split = solve(split, rep)
    np.testing.assert_allclose(u_split, u_whole[rep], rtol=0, atol=1e-12 * np.abs(u_whole).max())
    jumps = u_split[split.interfaces[:, 2:]] - u_split[split.interfaces[:, :2]]
    assert np.abs(jumps).max() == 0.0


def test_untied_crack_changes_the_solution():
    """The contrast: the same split mesh, untied, opens under the lateral pressure."""
    m = cracked_specimen(1.0, 1.0, nx=4, ny=4, crack=False)
    split = insert_interfaces(m, edges_on(m, chain((0, 2), (2, 2))))
    u = solve(split, np.arange(split.n_nodes))
    jumps = u[split.interfaces[:, 2:]] - u[split.interfaces[:, :2]]
    assert np.abs(jumps).max() > 1e-3 * np.abs(u).max()
    tip = split.interfaces[:, 1] == split.interfaces[:, 3]
    assert tip.sum() == 1 and np.abs(jumps[tip, 1]).max() == 0.0  # the tip pair is one node


@pytest.mark.parametrize("seed", range(4))
def test_random_selections_against_a_plain_loop(seed):
    """Copies per node counted by walking each node's cells (a union-find loop): on selected
    nodes, fans = components of the incident cells joined across unselected edges."""
    m = grid(5, 4, tri=seed % 2 == 1)
    rng = np.random.default_rng(seed)
    sel = rng.random(internal_edges(m).edges.shape[0]) < 0.35
    new = insert_interfaces(m, sel)
    check_split(m, new, sel)
    ie = internal_edges(m)
    on_crack = set(ie.edges[sel].ravel().tolist())
    expected = 0
    for v in range(m.n_nodes):
        cells = [c for c in range(m.cells.shape[0]) if v in m.cells[c]]
        root = {c: c for c in cells}

        def find(c):
            while root[c] != c:
                c = root[c]
            return c

        for e, (c0, c1) in zip(ie.edges[~sel], ie.cells[~sel]):
            if v in e:
                root[find(c0)] = find(c1)
        expected += len({find(c) for c in cells}) if v in on_crack else 1
    assert new.n_nodes == expected


@pytest.mark.parametrize("tri", [False, True])
def test_a_pair_on_a_loop_cannot_open_alone(tri):
    """Surfaces on every edge, each node split into one copy per cell: round a node inside the mesh
    the pairs close a loop, so with every other pair held shut a pair there has no jump (its rows
    are in the span of the others': a crack tip inside the mesh stays shut, the RP warning's
    kinematics); on the boundary the fans are chains and each pair can open alone. looped_pairs
    tells them apart, also for a crack whose pairs are bridges."""
    from rockfrac.elements.interface_points import interface_points

    m = grid(3, 3, tri)
    for sel, expect_loops in ((all_edges(m), True), (edges_on(m, chain((0, 1), (3, 1), nx=3)), False)):
        new = insert_interfaces(m, sel)
        pts = interface_points(new.nodes, new.interfaces)
        jump = np.zeros((2 * pts.n, 2 * new.n_nodes))  # the jump operator: rows (point, component)
        for k in range(pts.n):
            for a in range(2):
                jump[2 * k + a, 2 * pts.plus[k] + a] += 1.0
                jump[2 * k + a, 2 * pts.minus[k] + a] -= 1.0
        looped = looped_pairs(pts.minus, pts.plus, new.n_nodes)
        assert looped.any() == expect_loops and (~looped).any()
        full = np.linalg.matrix_rank(jump)
        for k in range(pts.n):
            gain = full - np.linalg.matrix_rank(np.delete(jump, [2 * k, 2 * k + 1], axis=0))
            assert gain == (0 if looped[k] else 2), (k, looped[k])


def test_looped_pairs_are_the_graph_edges_on_a_cycle():
    """A 4-cycle of copies with a tail hanging off it and a doubled pair beside: the cycle's pairs and
    the doubled ones are looped, the tail's (bridges) are not; node numbers need not be contiguous."""
    minus = np.array([10, 11, 12, 13, 13, 14, 20, 20])
    plus = np.array([11, 12, 13, 10, 14, 15, 21, 21])
    np.testing.assert_array_equal(looped_pairs(minus, plus),
                                  [True, True, True, True, False, False, True, True])
