"""[cohesive] points = 'corners' (rockfrac.elements.cse_corners): the nodal rule cell by cell, a point at
each corner of each interface cell with its own state; RP with one multiplier per cell."""

from __future__ import annotations

import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest

from conftest import EVERY_EDGE, check_cohesive_tangent, check_tied_every_edge, check_uniform_tractions_3d

from rockfrac.api import make_case, run
from rockfrac.case.build import build
from rockfrac.case.schema import CaseError, parse_case
from rockfrac.case.shares import cut_shares
from rockfrac.elements.cse_corners import CornerEP, CornerRP, corner_points, held_pairs_separated, holding_pairs
from rockfrac.mesh import rock_tests as rt
from rockfrac.mesh.interfaces import tied_nodes
from rockfrac.output.csvout import read_csv
from rockfrac.runner import run_case
from rockfrac.studies import table1

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
from edge_points import rocking_block  # noqa: E402
from test_edge_points import small_grains  # noqa: E402

RP_CORNERS = dict(table1.CSE_LAW, form="rp", where="all", points="corners")
EP_CORNERS = dict(table1.CSE_LAW, form="ep", where="all", points="corners", kn=1e13, kt=1e13)


def test_rp_corners_on_every_edge_held_shut_give_the_unsplit_solution(tmp_path):
    """The patch test: RP corner points on every edge of the 4 x 6 specimen (every cell its own corners),
    held shut by a uniform stress: the unsplit specimen's loads, no jump, each corner's traction sigma . n,
    one multiplier pair per edge, and no warning about loops."""
    run_case(parse_case(EVERY_EDGE), tmp_path / "a")
    s = run_case(parse_case(dict(EVERY_EDGE, cohesive=RP_CORNERS)), tmp_path / "b")
    assert s.result.completed
    group = s.built.cohesives[0]
    assert isinstance(group, CornerRP) and group.points.n == 2 * 38 and group.extra_span() == 2 * 38
    check_tied_every_edge(tmp_path / "a", tmp_path / "b", rtol=1e-9, jump=1e-15)
    assert not [w for w in s.warnings or [] if "loops" in w]


@pytest.fixture(scope="module", params=["tet4", "hex8"])
def box(tmp_path_factory, request):
    """A unit box of 2 x 2 x 2 cells (tetrahedra: each hexahedron split by Gmsh)."""
    return rt.box(tmp_path_factory.mktemp("box") / "box.msh", (1.0, 1.0, 1.0), (2, 2, 2), element=request.param)


def test_rp_corners_on_every_face_held_shut_give_the_unsplit_solution(box, tmp_path):
    """3D: RP corner points on every internal face of the box (tetrahedra: up to 8 faces round an edge), too
    strong to yield, under the uniform stress diag(-1, -0.5, -2) MPa: the unsplit displacements, no jump,
    and each corner's traction sigma . n, shear included."""
    sigma = np.diag([-1.0e6, -5.0e5, -2.0e6])
    stages = [{"name": "load", "displacement": {"bottom": {"z": 0.0}, "left": {"x": 0.0}, "front": {"y": 0.0}},
               "pressure": {"top": 2e6, "right": 1e6, "back": 5e5}}]

    def case(**extra):
        return make_case(mesh={"kind": "gmsh", "file": str(box)}, bulk={"E": 2e10, "nu": 0.25}, stages=stages,
                         output={"picture": False}, **extra)

    plain = run(case(), tmp_path / "plain")
    strong = {"where": "all", "law": "bilinear", "sigma_c": 1e9, "Gc": 1e3, "beta": 1.0, "points": "corners",
              "form": "rp", "augmentation": 1e13}
    split = run(case(cohesive=strong), tmp_path / "split")
    group = split.built.cohesives[0]
    assert isinstance(group, CornerRP)
    rep = tied_nodes(split.built.mesh)
    u, u0 = split.displacement(), plain.displacement()
    assert np.abs(u - u0[rep]).max() <= 1e-10 * np.abs(u0).max()
    check_uniform_tractions_3d(tmp_path / "split" / "points.csv", sigma, 2e6)


@pytest.mark.parametrize("cohesive", [EP_CORNERS, dict(RP_CORNERS, augmentation=1e13)], ids=["ep", "rp"])
def test_corner_points_tangent_is_the_derivative_of_their_forces(cohesive):
    """The consistent tangent of corner points, the cells' shared multipliers included, against central
    differences of the internal forces at a state where some points are plastic and others are not."""
    built = build(parse_case(dict(EVERY_EDGE, cohesive=cohesive)))
    model = built.model
    model.set_dirichlet(built.stages[0].dirichlet)
    check_cohesive_tangent(model, built.cohesives[0], seed=3, step=1e-6)


def test_corner_weights_are_the_cells_nodal_rule():
    """A corner's weight is its share of the cell (half an edge; int N_a dA of a face), the cell's frame
    is each corner's, and the points of an RP cell share its multipliers."""
    nodes2 = np.array([[0.0, 0.0], [3.0, 4.0], [0.0, 0.0], [3.0, 4.0]])
    pts = corner_points(nodes2, np.array([[0, 1, 2, 3]]))
    np.testing.assert_allclose(pts.weight, [2.5, 2.5])
    np.testing.assert_allclose(pts.frame[0, 1], [-0.8, 0.6])  # n: t = (0.6, 0.8) turned by +90 degrees
    x = np.array([[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [2.0, 1.0, 0.0], [0.0, 1.0, 0.0]])
    pts3 = corner_points(np.concatenate([x, x]), np.arange(8)[None, :])
    np.testing.assert_allclose(pts3.weight, [0.5] * 4)  # a rectangle: a quarter each
    np.testing.assert_allclose(np.abs(pts3.frame[:, 2, 2]), 1.0)


def test_a_pair_is_separated_only_where_all_its_corner_points_are():
    """Two edges along a line share the middle node pair (1, 4): it is separated only when both of the
    corner points on it are."""
    nodes = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]] * 2)
    pts = corner_points(nodes, np.array([[0, 1, 3, 4], [1, 2, 4, 5]]))
    hit = np.array([True, True, False, False])
    np.testing.assert_array_equal(held_pairs_separated(pts, hit), [[0, 3]])
    hit = np.array([True, True, True, False])
    np.testing.assert_array_equal(held_pairs_separated(pts, hit), [[0, 3], [1, 4]])


def test_a_pair_split_between_ranks_is_separated_only_where_no_rank_holds_it():
    """Two quads either side of a crack of two edges; the edges' cells on two MPI ranks share the middle
    pair (1, 4). Each rank separates the pairs all of whose points it holds are gone, and names those
    it still holds: the fragments are those of the whole set, whichever rank's points go first."""
    from rockfrac.mesh.mesh import Mesh
    from rockfrac.output.fragments import Fragments

    nodes = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]] * 2 + [[0.0, -1.0], [1.0, -1.0], [2.0, -1.0],
                                                                  [0.0, 1.0], [1.0, 1.0], [2.0, 1.0]])
    cells = np.array([[6, 7, 1, 0], [7, 8, 2, 1], [3, 4, 10, 9], [4, 5, 11, 10]])  # below (0-2), above (3-5)
    interfaces = np.array([[0, 1, 3, 4], [1, 2, 4, 5]])
    mesh = Mesh(nodes=nodes, cells=cells, cell_type="quad4", interfaces=interfaces)
    frag = Fragments(mesh)
    pts = corner_points(nodes, interfaces)
    pts.index = np.arange(pts.n)
    ranks = [pts.subset(pts.cell == c) for c in (0, 1)]
    # each hit pattern, and the pieces if each rank's separated pairs were taken as they are
    for hit, naive in (([True, True, True, False], 1), ([True, True, False, True], 2), ([False, True, True, True], 1),
                       ([True, True, True, True], 2)):
        hit = np.array(hit)
        whole = frag.pieces(held_pairs_separated(pts, hit)).count
        mine = [hit[r.index] for r in ranks]
        sep = np.concatenate([held_pairs_separated(r, h) for r, h in zip(ranks, mine)])
        held = np.concatenate([holding_pairs(r, h) for r, h in zip(ranks, mine)])
        assert frag.pieces(sep, held).count == whole == (2 if hit.all() else 1)
        assert frag.pieces(sep).count == naive  # rank 0 lost the middle pair, rank 1 holds it


def test_rp_corners_rock_a_block_as_nodal_points_do(tmp_path):
    """A block on one horizontal surface (8 edges), pressed, then pushed sideways at its top: the heel
    opens in tension while the toe is pressed. RP corner points follow nodal RP points through the
    peak and the rocking (peak, end and dissipation to 1e-3) in as many steps, and their energy
    balance closes with the corners' elastic deviations stored. (Edge points stall here: active-set
    cycles at the heel, benchmarks/README.md, "A block rocking on one surface".)"""
    out = {}
    for points in ("nodes", "corners"):
        s = run_case(parse_case(rocking_block("rp", points, 100, 5e-3, 1e13, 8), points), tmp_path / points)
        assert s.result.completed, s.result.message
        h = read_csv(tmp_path / points / "history.csv")
        assert np.abs(h["energy_error"]).max() < 1e-8 * h["W_external"][-1]
        out[points] = (h["R_top_x"].max(), h["R_top_x"][-1], h["D_dissipated"][-1], s.result.steps)
    assert isinstance(s.built.cohesives[0], CornerRP)
    for a, b in zip(out["corners"][:3], out["nodes"][:3]):
        assert a == pytest.approx(b, rel=1e-3)
    assert out["nodes"][1] < 0.95 * out["nodes"][0] or out["nodes"][2] > 0.1  # the surface has yielded
    assert out["corners"][3] <= out["nodes"][3] + 5


def test_rp_corner_points_follow_ep_corner_points_where_nodal_rp_points_stall(run):
    """Like for like on every edge of two grains in a matrix (8 x 16 mm, 704 edges; r = kn = 2e12 Pa/m,
    one relaxation time): RP corners run the stage in steps of EP's order and carry EP's load and
    dissipation (measured: 0.24 % and 2.8 %, rigid against a penalty; nodal RP points stall at 0.8 of the
    stage: rings of pairs round the nodes)."""
    h_ep, _, s_ep = run(small_grains("ep", "corners"), "ep")
    h_rp, _, s_rp = run(small_grains("rp", "corners"), "rp")
    assert s_ep.result.completed and s_rp.result.completed, s_rp.result.message
    assert isinstance(s_rp.built.cohesives[0], CornerRP) and isinstance(s_ep.built.cohesives[0], CornerEP)
    assert h_rp["D_dissipated"][-1] > 0.0
    assert h_rp["R_top_y"][-1] == pytest.approx(h_ep["R_top_y"][-1], rel=0.01)
    assert h_rp["D_dissipated"][-1] == pytest.approx(h_ep["D_dissipated"][-1], rel=0.04)
    assert s_rp.result.steps <= 2 * s_ep.result.steps
    for h in (h_ep, h_rp):
        assert abs(h["energy_error"][-1]) <= 1e-7 * h["W_external"][-1]


def test_corner_points_refuse_what_they_do_not_do(tmp_path):
    """Refused by name before any step: IMPL-EX (integration or fallback), and RP on a surface of triangles
    (the joint of examples/rock_tests/triaxial: 138 faces on 83 node pairs), whose cells' multipliers its
    pairs cannot determine (it stopped at its first steps, "RP return map failed", its multipliers MPa
    off), on one process and on MPI ranks (rank 0's whole set); RP faces likewise."""
    with pytest.raises(CaseError, match="points = 'corners' takes each cell's own normal"):
        parse_case(dict(EVERY_EDGE, cohesive=dict(EP_CORNERS, integration="implex")))
    data = dict(EVERY_EDGE, cohesive=EP_CORNERS, solver={"fallback": "implex"})
    with pytest.raises(CaseError, match="fallback = 'implex' is for points = 'nodes'"):
        build(parse_case(data))
    triaxial = Path(__file__).resolve().parents[1] / "examples" / "rock_tests" / "triaxial"
    joint = tomllib.loads((triaxial / "joint.toml").read_text())
    joint["mesh"]["file"] = str(triaxial / joint["mesh"]["file"])
    coh = joint["cohesive"]
    coh.update(form="rp", augmentation=coh.pop("kn"))
    coh.pop("kt")
    for points in ("corners", "faces"):
        coh["points"] = points
        with pytest.raises(CaseError, match=f"points = '{points}' .* 138 cells share 83 node pairs, which leave the "
                                            "multipliers of 55 of them undetermined"):
            build(parse_case(joint))
        with pytest.raises(CaseError, match="55 of them undetermined"):
            cut_shares(parse_case(joint), "<case>", 2, lambda mesh: None)
    coh["points"] = "nodes"
    assert build(parse_case(joint)).cohesives[0].n_extra == 3 * 83


def test_rp_corner_points_carry_the_disc_to_its_splitting_load(tmp_path):
    """The coarse Brazilian disc with RP corner points on every internal edge (nodal points' in
    tests/test_rock_tests.py): the peak is the Brazilian estimate to 2 % (0.991 measured; nodal 0.993),
    with no ring round a node to hold the first yielded points shut."""
    from test_rock_tests import brazilian_estimate, rp_everywhere_disc

    s = run_case(parse_case(rp_everywhere_disc("corners"), "disc"), tmp_path / "disc")
    h = read_csv(tmp_path / "disc" / "history.csv")
    assert isinstance(s.built.cohesives[0], CornerRP)
    assert "points lie on loops" not in (tmp_path / "disc" / "run.log").read_text()
    assert -h["R_load_top_y"].min() == pytest.approx(brazilian_estimate(8e6), rel=0.02)
    assert h["n_plastic"].max() >= 10 and s.result.steps > 30  # edges yielded along the loaded diameter
