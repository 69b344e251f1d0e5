"""[cohesive] points = 'edges' (rockfrac.elements.cse_facets): one point per edge on its mean jump, with an
moment on the edge's relative rotation (elastic up to the tension cap), instead of one point per node pair."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from conftest import EVERY_EDGE, check_cohesive_tangent, check_tied_every_edge

from rockfrac.api import make_case
from rockfrac.case.build import build
from rockfrac.case.schema import CaseError, parse_case
from rockfrac.elements.cse_facets import FacetEP, FacetRP
from rockfrac.mesh import rock_tests as rt
from rockfrac.output.csvout import read_csv
from rockfrac.runner import run_case
from rockfrac.studies import table1

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
from fragmentation import grains_case  # noqa: E402

RP_EDGES = dict(table1.CSE_LAW, form="rp", where="all", points="edges")
EP_EDGES = dict(table1.CSE_LAW, form="ep", where="all", points="edges", kn=1e13, kt=1e13)


def test_rp_edges_on_every_edge_held_shut_give_the_unsplit_solution(tmp_path):
    """The patch test: RP edge points on every edge of the 4 x 6 specimen (every cell its own corners),
    held shut by a uniform stress: the unsplit specimen's loads, no jump, and each edge's multipliers
    are the tractions sigma . n. Edge points close no ring round a node: no junction term, no
    circulation, and no warning about loops."""
    run_case(parse_case(EVERY_EDGE), tmp_path / "a")
    s = run_case(parse_case(dict(EVERY_EDGE, cohesive=RP_EDGES)), tmp_path / "b")
    assert s.result.completed
    group = s.built.cohesives[0]
    assert isinstance(group, FacetRP) and group.points.n == 38  # the 4 x 6 quads' internal edges
    check_tied_every_edge(tmp_path / "a", tmp_path / "b", rtol=1e-9, jump=1e-15)
    p = read_csv(tmp_path / "b" / "points.csv")
    assert np.abs(p["T_t"]).max() < 1e-9 * np.abs(p["T_n"]).max()  # sigma . n has no shear on these edges
    assert not [w for w in s.warnings or [] if "loops" in w]


def _model(cohesive: dict):
    built = build(parse_case(dict(EVERY_EDGE, cohesive=cohesive)))
    model = built.model
    model.set_dirichlet(built.stages[0].dirichlet)
    return built, model


@pytest.mark.parametrize("cohesive", [EP_EDGES, dict(RP_EDGES, augmentation=1e13)], ids=["ep", "rp"])
def test_edge_points_tangent_is_the_derivative_of_their_forces(cohesive):
    """The consistent tangent of edge points, moment included, against central differences of the
    internal forces, at a state where some points are plastic and others are not, and some moments
    are on their caps (EP: jumps of a few strengths over kn; RP: multipliers of that size, and jumps;
    k = 1e13 Pa/m)."""
    built, model = _model(cohesive)
    group = built.cohesives[0]
    check_cohesive_tangent(model, group, seed=3, step=1e-4)
    assert 0 < np.count_nonzero(group.capped) < group.points.n  # capped moments and elastic ones


def test_the_moment_is_the_penalty_energy_of_a_linear_normal_jump():
    """An edge whose normal jump runs linearly from -a to +a along it (mean zero, so the law's point sees
    no jump): the moment's energy k L g^2 / 24 is the penalty's energy of that jump, int kn j(s)^2 / 2
    ds = kn a^2 L / 6 (Gauss), and the edge's forces are that energy's gradient (below the cap: its end
    tractions' deviation kn a = 1e4 Pa, where the virgin tensile strength is 15680 Pa)."""
    built, model = _model(EP_EDGES)
    group = built.cohesives[0]
    assert isinstance(group, FacetEP)
    d, a, k = 2, 1e-9, 5
    n = group.points.frame[k, 1]
    m0, m1, p0, p1 = (group.jump_dofs[k, i * d:(i + 1) * d] for i in range(4))
    u = np.zeros(model.n_dofs)
    u[p0] += -0.5 * a * n
    u[m0] -= -0.5 * a * n
    u[p1] += 0.5 * a * n
    u[m1] -= 0.5 * a * n
    length = group.points.weight[k]
    assert np.abs(group.jumps(u)[k]).max() < 1e-27

    def energy(v: np.ndarray) -> float:  # the edge's moment
        return float(group.moment_energies(v)[k])

    j0, j1 = n @ (u[p0] - u[m0]), n @ (u[p1] - u[m1])
    s, w = np.polynomial.legendre.leggauss(3)
    jump = 0.5 * (j0 + j1) + 0.5 * (j1 - j0) * s  # the normal jump along the edge (its mean is zero)
    assert energy(u) == pytest.approx(0.5 * 1e13 * np.sum(w * jump ** 2) * length / 2, rel=1e-12)
    assert energy(u) == pytest.approx(1e13 * a * a * length / 6, rel=1e-12)
    model.begin_step()
    fe = group.evaluate(u, np.zeros(model.n_dofs)).fe[k]
    for col, j in enumerate(group.jump_dofs[k]):
        e = np.zeros(model.n_dofs)
        e[j] = 1e-3 * a
        grad = (energy(u + e) - energy(u - e)) / (2e-3 * a)
        assert fe[col] == pytest.approx(grad, rel=1e-8, abs=1e-12 * np.abs(fe).max())


def _bent_edge(group, k: int, mean: float, rho: float, n_dofs: int) -> np.ndarray:
    """Displacements that give edge k of ``group`` the normal jumps mean -+ rho / 2 at its ends [m]."""
    d = 2
    n = group.points.frame[k, 1]
    m0, m1, p0, p1 = (group.jump_dofs[k, i * d:(i + 1) * d] for i in range(4))
    u = np.zeros(n_dofs)
    u[p0] += (mean - 0.5 * rho) * n
    u[p1] += (mean + 0.5 * rho) * n
    return u


def test_a_bent_edge_carries_its_moment_up_to_the_tension_cap():
    """An edge in compression (mean normal jump -1e-8 m, T_n = kn x that = -1e5 Pa) bent by a normal jump
    difference rho: elastic, its end tractions deviate by kn rho / 2; bent further, the opening end's
    traction T_n + Delta stops at the tensile strength chi and the rest of rho is plastic; the moment's
    stored energy is L Delta^2 / (6 kn), and its dissipation the work Q d rho_p (Q = L Delta / 6). An
    edge that has opened past its strength (T_n on the cap) is a hinge: no moment."""
    built, model = _model(EP_EDGES)
    group = built.cohesives[0]
    k, kn, length = 5, 1e13, group.points.weight[5]
    zero = np.zeros(model.n_dofs)

    def bend(mean: float, rho: float) -> tuple[float, float, float]:
        model.begin_step()
        group.evaluate(_bent_edge(group, k, mean, rho, model.n_dofs), zero)
        chi = group.law.records(group.trial)[group.law.tensile_record][k]
        return group.trial[k, 1], 6.0 * group._force_trial[k, 1] / length, chi  # T_n, Delta, chi

    t_n, delta, chi = bend(-1e-8, 1e-9)
    assert t_n == pytest.approx(-1e5, rel=1e-12) and chi == 15680.0
    assert delta == pytest.approx(0.5 * kn * 1e-9, rel=1e-12) and not group.capped[k]
    rho = 1e-7  # elastic: Delta = 5e5 Pa, past the cap chi - T_n = 115680 Pa
    t_n, delta, chi = bend(-1e-8, rho)
    assert group.capped[k] and t_n + delta == pytest.approx(chi, rel=1e-12)
    u = _bent_edge(group, k, -1e-8, rho, model.n_dofs)
    group.commit()
    rho_p = rho - 2.0 * delta / kn
    assert group.bend_plastic[k, 1] - group.bend_plastic[k, 0] == pytest.approx(rho_p, rel=1e-12)
    assert group.moment_energies(u)[k] == pytest.approx(length * delta ** 2 / (6.0 * kn), rel=1e-9)
    assert group.moment_dissipated == pytest.approx(0.5 * length * delta / 6.0 * rho_p, rel=1e-9)
    t_n, delta, chi = bend(1e-6, 1e-7)  # opened 64 times its elastic limit: on the cap, a hinge
    assert group.trial[k, group.mode] == 1.0 and t_n == pytest.approx(chi, rel=1e-9)
    assert abs(delta) <= 1e-9 * 15680.0


def small_grains(form: str, points: str) -> dict:
    """Two grains in a matrix, 8 x 16 mm (368 quads, 704 internal edges), surfaces on every edge
    (three sets), viscous, compressed by 0.1 mm in 5 load steps: nodal RP points stop at 0.8 of it
    (rings round the nodes hold them shut: benchmarks/README.md, "Points per edge")."""
    d = grains_case(0.002, Path("."))
    d["mesh"].update(width=0.008, height=0.016, n_grains=2, radius_min=0.0015, radius_max=0.0025)
    d["output"] = {"vtk": False, "picture": False, "points": False}
    stage = d["stages"][0]
    stage.update(steps=5, control="load")
    stage.pop("max_steps")
    stage["displacement"]["top"]["y"] = -1e-4
    stage["stop"]["below_peak_fraction"] = 0.05
    for c in d["cohesive"]:
        c.update(form=form, viscosity=2.5e-5, points=points)
        if form == "rp":
            del c["kn"], c["kt"]
            c["augmentation"] = 2e12
    return d


def test_rp_edge_points_follow_ep_edge_points_where_nodal_rp_points_stall(run):
    """Like for like: RP and EP edge points (r = kn = 2e12 Pa/m, one relaxation time) through the
    compression of a small grain-matrix specimen with surfaces on every edge, past the load at which
    nodal RP points stall. RP runs the stage in steps of EP's order and carries EP's load and
    dissipation to 1 % and 3 %."""
    h_ep, _, s_ep = run(small_grains("ep", "edges"), "ep")
    h_rp, _, s_rp = run(small_grains("rp", "edges"), "rp")
    assert s_ep.result.completed and s_rp.result.completed, s_rp.result.message
    assert h_rp["D_dissipated"][-1] > 0.0  # surfaces have yielded and slid
    assert h_rp["R_top_y"][-1] == pytest.approx(h_ep["R_top_y"][-1], rel=0.01)
    assert h_rp["D_dissipated"][-1] == pytest.approx(h_ep["D_dissipated"][-1], rel=0.03)
    assert s_rp.result.steps <= 2 * s_ep.result.steps
    for h in (h_ep, h_rp):  # the work is the stored energy, the moments' included, and the dissipation
        assert abs(h["energy_error"][-1]) <= 1e-7 * h["W_external"][-1]


def test_edge_points_refuse_what_they_do_not_do(tmp_path):
    """points = 'edges' with smoothed normals, nested multipliers or IMPL-EX, on a 3D mesh, or with the
    IMPL-EX fallback: a clear error before any step."""
    for extra, word in (({"normals": "smoothed"}, "normals = 'smoothed'"),
                        ({"multipliers": "nested"}, "multipliers = 'nested'")):
        with pytest.raises(CaseError, match=word):
            parse_case(dict(EVERY_EDGE, cohesive=dict(RP_EDGES, **extra)))
    with pytest.raises(CaseError, match="integration = 'implex'"):
        parse_case(dict(EVERY_EDGE, cohesive=dict(EP_EDGES, integration="implex")))
    with pytest.raises(CaseError, match="fallback"):
        build(parse_case(dict(EVERY_EDGE, cohesive=EP_EDGES, solver={"fallback": "implex"})))
    with pytest.raises(CaseError, match="this mesh is 2D, whose interface cells are edges: points = 'edges'"):
        build(parse_case(dict(EVERY_EDGE, cohesive=dict(EP_EDGES, points="faces"))))
    msh = rt.box(tmp_path / "box.msh", (1.0, 1.0, 1.0), (2, 2, 2), element="tet4")
    box = make_case(mesh={"kind": "gmsh", "file": str(msh)}, bulk={"E": 2e10, "nu": 0.25},
                    cohesive=dict(RP_EDGES, augmentation=1e12),
                    stages=[{"name": "p", "displacement": {"bottom": {"x": 0.0, "y": 0.0, "z": 0.0}},
                             "pressure": {"top": 1e6}}])
    with pytest.raises(CaseError, match="this mesh is 3D, whose interface cells are faces: points = 'faces'"):
        build(box)


@pytest.mark.parametrize("cohesive", [EP_EDGES, RP_EDGES], ids=["ep", "rp"])
def test_a_share_of_no_edges_evaluates_to_nothing(cohesive):
    """An MPI rank may hold none of a set's edges: its group (made from no cells, with the set's places
    ``index``) evaluates, measures and separates to empty arrays, where a reshape of nothing once
    raised on that rank alone and left the other waiting."""
    built, model = _model(cohesive)
    whole = built.cohesives[0]
    law = whole.law
    cells = np.zeros((0, 4), dtype=np.int64)
    if isinstance(whole, FacetRP):
        group = FacetRP(cells, built.mesh.nodes, law, whole.aug, index=np.zeros(0, dtype=np.int64))
    else:
        group = FacetEP(cells, built.mesh.nodes, law, index=np.zeros(0, dtype=np.int64))
    u = np.zeros(model.n_dofs)
    assert group.points.n == 0 and group.jumps(u).shape == (0, 2) and group.normal_jumps(u).shape == (0, 2)
    measure = group.jump_measure(model.n_dofs)
    value, grad = measure(u)
    assert value == 0.0 and not grad.any()
    pairs, length = group.separated(0.99)
    assert pairs.shape == (0, 2) and length == 0.0
    assert group.moment_energy(u) == 0.0


def test_facet_points_take_their_places_among_the_sets():
    """A share of a set's edges (an MPI rank's) keeps each edge's place among the set's as its points'
    index and cell, which number the RP multipliers and the rows of points.csv over the ranks."""
    built, _ = _model(EP_EDGES)
    whole = built.cohesives[0]
    keep = np.arange(3, whole.points.n, 4)
    part = FacetEP(whole.points.segments[keep], built.mesh.nodes, whole.law, index=keep)
    np.testing.assert_array_equal(part.points.index, keep)
    np.testing.assert_array_equal(part.points.cell, keep)
    np.testing.assert_allclose(part.points.weight, whole.points.weight[keep], rtol=1e-15)
    np.testing.assert_allclose(part.points.frame, whole.points.frame[keep], rtol=1e-15)


def test_edge_points_break_a_notched_beam_as_nodal_points_do(tmp_path):
    """Three-point bending of the notched beam (tests/test_rock_tests.py) with RP edge points on the
    ligament: the edges at the crack tip open at one end, which the bending's cap allows (an elastic
    moment held them: the load rose to 2e5 N/m, 6.6 times the peak, with nothing broken). The peak is the
    nodal points' to 0.5 %, and the dissipation with the load's tail still to come, P delta, is G_c times
    the ligament to 2 %, as for nodal points."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from test_rock_tests import example

    msh = rt.notched_beam(tmp_path / "beam.msh", element_size=0.0025)
    peaks = {}
    for points in ("nodes", "edges"):
        data = example("bending/notched_beam.toml", msh, **{"0__steps": 500})
        data["cohesive"]["points"] = points
        s = run_case(parse_case(data, points), tmp_path / points)
        h = read_csv(tmp_path / points / "history.csv")
        assert s.result.completed and "fell below 0.005" in s.result.message
        gc_l = data["cohesive"]["Gc"] * 0.035
        tail = abs(h["R_load_y"][-1] * h["u_load_y"][-1]) / gc_l
        assert 0.9 < h["D_dissipated"][-1] / gc_l < 1.0
        assert h["D_dissipated"][-1] / gc_l + tail == pytest.approx(1.0, abs=0.02)
        assert np.abs(h["energy_error"]).max() < 1e-9 * h["W_external"][-1]
        assert ("D_bending" in h) == (points == "edges")
        peaks[points] = -h["R_load_y"].min()
    assert peaks["edges"] == pytest.approx(peaks["nodes"], rel=5e-3)
    group = s.built.cohesives[0]
    assert isinstance(group, FacetRP) and group.moment_dissipated > 0.0
    assert h["D_bending"][-1] == pytest.approx(group.moment_dissipated, rel=1e-12)  # one unit thickness
    assert 0.0 < h["D_bending"][-1] < 0.1 * h["D_dissipated"][-1]


def test_rp_edge_points_carry_the_disc_to_its_splitting_load(tmp_path):
    """The coarse Brazilian disc with RP edge points on every internal edge (tests/test_rock_tests.py has
    the nodal points'): the peak is the Brazilian estimate to 2 % (0.990 measured; nodal 0.993), with
    no ring round a node to hold the first yielded points shut."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from test_rock_tests import brazilian_estimate, rp_everywhere_disc

    s = run_case(parse_case(rp_everywhere_disc("edges"), "disc"), tmp_path / "disc")
    h = read_csv(tmp_path / "disc" / "history.csv")
    assert "points lie on loops" not in (tmp_path / "disc" / "run.log").read_text()
    assert -h["R_load_top_y"].min() == pytest.approx(brazilian_estimate(8e6), rel=0.02)
    assert h["n_plastic"].max() >= 10 and s.result.steps > 30  # edges yielded along the loaded diameter
