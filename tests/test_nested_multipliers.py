"""RP surfaces with nested multipliers ([cohesive] multipliers = "nested"): the saddle point's solution
without its multiplier unknowns, and the Anderson mixing of their updates."""

import numpy as np
import pytest
from conftest import EVERY_EDGE, P, TABLE1, THETA, W, check_tied_every_edge, paper_case

from rockfrac import analytic
from rockfrac.case.schema import CaseError, parse_case
from rockfrac.elements.cse_nested import CohesiveRPNested
from rockfrac.fem.anderson import AndersonMixing
from rockfrac.output.csvout import read_csv
from rockfrac.runner import run_case
from rockfrac.studies import table1


def _linear_map(seed: int = 0):
    """x <- M x + b with eigenvalues 0.99, 0.5 and -0.9 (plain iteration: 0.99^k)."""
    rng = np.random.default_rng(seed)
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    m = q @ np.diag([0.99, 0.5, -0.9]) @ np.linalg.inv(q)
    b = rng.normal(size=3)
    return m, b, np.linalg.solve(np.eye(3) - m, b)


def test_anderson_mixing_solves_a_linear_fixed_point_in_n_plus_one_updates():
    """Of depth >= n on an n-dimensional linear map, Anderson mixing is GMRES on (I - M) x = b: exact
    after n + 1 updates, where the plain iteration has barely moved; depth 0 is the plain iteration."""
    m, b, x_star = _linear_map()
    mixing = AndersonMixing(3)
    x = np.zeros(3)
    for _ in range(4):
        x = mixing.next(x, m @ x + b, np.ones(3))
    # to round-off: the mixing solves the normal equations of the residuals' differences, whose Gram matrix
    # has a condition number of 5e6 at the 4th update here (2e-10 measured with numpy 2.4)
    assert np.linalg.norm(x - x_star) < 1e-8 * np.linalg.norm(x_star)
    plain, y = AndersonMixing(0), np.zeros(3)
    for _ in range(4):
        y = plain.next(y, m @ y + b, np.ones(3))
    z = np.zeros(3)
    for _ in range(4):
        z = m @ z + b
    np.testing.assert_array_equal(y, z)
    assert np.linalg.norm(y - x_star) > 0.5 * np.linalg.norm(x_star)
    # a reset forgets the history: the next update is the plain one again
    mixing.reset()
    np.testing.assert_array_equal(mixing.next(x_star + 1.0, m @ (x_star + 1.0) + b, np.ones(3)), m @ (x_star + 1.0) + b)
    with pytest.raises(ValueError, match="depth"):
        AndersonMixing(-1)


def test_nested_multipliers_give_the_saddle_points_history_on_the_papers_rp_case(tmp_path):
    """The paper's RP case through activation and softening: the same steps, loads and dissipation as
    with the multipliers among the unknowns (both meet the same equations to 1e-8), the peak at the
    closed-form activation force (located by the rigid prediction), no multiplier unknowns, and the
    updates in run.log."""
    histories, summaries = {}, {}
    for how in ("unknowns", "nested"):
        case = paper_case("rp", axial_displacement=3e-3, axial_steps=100)
        case["cohesive"]["multipliers"] = how
        summaries[how] = run_case(parse_case(case), tmp_path / how)
        assert summaries[how].result.completed, summaries[how].result.message
        histories[how] = read_csv(tmp_path / how / "history.csv")
    a, b = histories["unknowns"], histories["nested"]
    np.testing.assert_allclose(b["u_axial"], a["u_axial"], rtol=1e-12)
    np.testing.assert_allclose(b["F_axial"], a["F_axial"], rtol=1e-7)
    np.testing.assert_allclose(b["D_dissipated"][-1], a["D_dissipated"][-1], rtol=1e-7)
    mc = analytic.mohr_coulomb_force(P, THETA, TABLE1["c_p"], np.tan(TABLE1["phi_p"]), W)
    assert b["F_axial"].max() == pytest.approx(mc, rel=1e-3)
    assert b["F_axial"][-1] < 0.6 * b["F_axial"].max()
    model = summaries["nested"].built.model
    assert model.n_dofs == 2 * summaries["nested"].built.mesh.n_nodes
    assert isinstance(summaries["nested"].built.cohesives[0], CohesiveRPNested)
    assert model.n_dofs < summaries["unknowns"].built.model.n_dofs
    log = (tmp_path / "nested" / "run.log").read_text()
    assert "multipliers updated (nested: their rows were at" in log


def test_nested_rp_on_every_edge_is_the_unsplit_elastic_solution_with_physical_junction_tractions(tmp_path):
    """Every internal edge split (loops of 4 pairs round each interior node) and tied by nested RP
    surfaces: the unsplit elastic response, no jump, and at the junctions the physical tractions
    sigma . n: an update never changes a loop's circulation (its jumps sum to zero), which stays the
    committed one, zero here."""
    run_case(parse_case(EVERY_EDGE), tmp_path / "a")
    s = run_case(parse_case(dict(EVERY_EDGE, cohesive=dict(table1.CSE_LAW, form="rp", where="all",
                                                             multipliers="nested"))), tmp_path / "b")
    assert s.result.completed
    check_tied_every_edge(tmp_path / "a", tmp_path / "b", rtol=1e-9, jump=1e-15)


@pytest.mark.parametrize("edit,expected", [
    ({"form": "ep", "kn": 1e12, "kt": 1e12, "multipliers": "nested"}, "multipliers only applies to form = 'rp'"),
    ({"form": "rp", "multipliers": "uzawa"}, "multipliers"),
])
def test_the_multipliers_key_is_checked(edit, expected):
    case = paper_case("rp")
    case["cohesive"].update(edit)
    with pytest.raises(CaseError, match=expected):
        parse_case(case, "case.toml")


def test_nested_rp_joints_in_3d_slide_as_the_saddle_points_do(tmp_path):
    """A 3D stack of tetrahedra with RP joints, pressed, then its top dragged until the joints slide
    (tests/test_layered_joints_3d.py): nested multipliers give the saddle point's history."""
    from test_layered_joints_3d import LAW, NU, E, P

    from rockfrac.api import make_case, run
    from rockfrac.mesh import rock_tests as rt

    box = rt.box(tmp_path / "b.msh", (1.0, 1.0, 1.0), (2, 2, 4), element="tet4", layers=2)
    histories = {}
    for how in ("unknowns", "nested"):
        case = make_case(mesh={"kind": "gmsh", "file": str(box)}, bulk={"E": E, "nu": NU},
                         cohesive={"where": "boundaries", "form": "rp", "augmentation": 1e12, "multipliers": how, **LAW},
                         stages=[{"name": "press", "displacement": {"bottom": {"x": 0.0, "y": 0.0, "z": 0.0}},
                                  "pressure": {"top": P}},
                                 {"name": "drag", "steps": 6, "pressure": {"top": P},
                                  "displacement": {"bottom": {"x": 0.0, "y": 0.0, "z": 0.0},
                                                   "top": {"x": 1.75e-4, "y": 0.0}}}],
                         solver={"linear": "superlu"}, output={"picture": False})
        r = run(case, tmp_path / how)
        assert r.completed, r.message
        histories[how] = r.history
    a, b = histories["unknowns"], histories["nested"]
    assert a["n_plastic"][-1] > 0
    np.testing.assert_array_equal(b["n_plastic"], a["n_plastic"])
    for q in ("R_top_x", "u_top_z", "D_dissipated"):
        np.testing.assert_allclose(b[q], a[q], rtol=0, atol=1e-7 * np.abs(a[q]).max())


def test_multiplier_updates_that_do_not_converge_end_the_step_and_say_so(tmp_path, monkeypatch):
    """With too few updates allowed (2 a step) the paper's nested RP case cannot meet its multiplier
    rows (its r is E / h: each update closes them by about half): the first step fails naming them,
    the stepping cuts back to min_step and the run stops cleanly, saying why in run.log."""
    from rockfrac.solve import newton

    monkeypatch.setattr(newton, "MAX_UPDATES", 2)
    case = paper_case("rp", axial_displacement=3e-4, axial_steps=10)
    case["cohesive"]["multipliers"] = "nested"
    s = run_case(parse_case(case), tmp_path / "out")
    assert not s.result.completed
    assert "the nested multipliers' rows are at" in s.result.message and "after 2 updates" in s.result.message
    log = (tmp_path / "out" / "run.log").read_text()
    assert "load increment below min_step" in log and "after 2 updates (lambda := T does not converge)" in log


def test_nested_rp_bar_under_energy_control_peaks_where_the_saddle_point_does(tmp_path):
    """The force-loaded bar (examples/path_following/bar_energy.toml): right after an update lambda := T
    the trial lambda + r h counts the elastic jump twice; unless the points inside their surfaces are
    held for that evaluation, the crack yields at 0.78 of the load (where it is 0.3 % inside) and the
    bar softens from 0.5 % below its peak. Held, it peaks at the located activation and follows the
    saddle point's path to the stop."""
    import tomllib
    from pathlib import Path

    text = (Path(__file__).resolve().parents[1] / "examples" / "path_following" / "bar_energy.toml").read_text()
    out = {}
    for multipliers in ("unknowns", "nested"):
        data = tomllib.loads(text)
        data["cohesive"]["multipliers"] = multipliers
        s = run_case(parse_case(data, multipliers), tmp_path / multipliers)
        assert s.result.completed, s.result.message
        out[multipliers] = read_csv(tmp_path / multipliers / "history.csv")
    h, g = out["unknowns"], out["nested"]
    first = int(np.flatnonzero(g["n_plastic"] > 0)[0])
    assert first == int(np.flatnonzero(h["n_plastic"] > 0)[0])
    assert g["load_factor"][first - 1] == pytest.approx(h["load_factor"][first - 1], rel=1e-9)
    assert np.abs(g["R_bottom_y"]).max() == pytest.approx(np.abs(h["R_bottom_y"]).max(), rel=1e-9)
    n = min(len(h["step"]), len(g["step"]))
    np.testing.assert_allclose(g["u_top_y"][:n], h["u_top_y"][:n], rtol=1e-6)
    np.testing.assert_allclose(g["R_bottom_y"][:n], h["R_bottom_y"][:n], rtol=1e-6, atol=1e-6 * 627.2)
