"""The loading program: stages on named groups, in-situ stress and gravity at t = 0, monitors,
reactions and the energy balance, against closed forms."""

from __future__ import annotations

import copy

import numpy as np
import pytest

from rockfrac.case.build import build
from rockfrac.case.schema import CaseError, parse_case
from rockfrac.output.csvout import read_csv
from rockfrac.runner import run_case

E, NU = 1e9, 0.25
W, H = 1.0, 2.0
LAW = {"GfI": 1e4, "GfII": 1e4, "chi_p": 1e6, "chi_r": 0.0, "c_p": 2e6, "c_r": 0.0, "phi_p": 0.5, "phi_r": 0.0,
       "psi_p": 0.0, "alpha_chi": 2e3, "alpha_c": 2e3, "alpha_phi": 9e2, "alpha_psi": 9e2}
SUPPORTS = {"bottom": {"y": 0.0}, "left": {"x": 0.0}}


def block(nx=2, ny=4, **extra) -> dict:
    case = {"mesh": {"kind": "block", "width": W, "height": H, "nx": nx, "ny": ny},
            "bulk": {"E": E, "nu": NU},
            "stages": [{"name": "load", "steps": 2, "displacement": SUPPORTS, "pressure": {"top": 1e6}}],
            "output": {"picture": False}}
    case.update(extra)
    return case


def run(case: dict, tmp_path, name="o"):
    run_case(parse_case(case, f"{name}.toml"), tmp_path / name)
    h = read_csv(tmp_path / name / "history.csv")
    return h


def test_top_pressure_on_a_block_matches_the_closed_form(tmp_path):
    case = block(monitors=[{"name": "corner", "kind": "displacement", "at": [W, H]},
                           {"name": "widening", "kind": "opening", "points": [[0.0, 1.0], [W, 1.0]]}])
    h = run(case, tmp_path)
    p, e_plane = 1e6, E / (1 - NU**2)
    eps_y, eps_x = -p / e_plane, p * NU * (1 + NU) / E  # plane strain, sigma_xx = 0
    np.testing.assert_allclose(h["u_top_y"][-1], eps_y * H, rtol=1e-12)
    np.testing.assert_allclose(h["corner_x"][-1], eps_x * W, rtol=1e-12)
    np.testing.assert_allclose(h["corner_y"][-1], eps_y * H, rtol=1e-12)
    np.testing.assert_allclose(h["widening"][-1], eps_x * W, rtol=1e-12)
    np.testing.assert_allclose(h["R_bottom_y"][-1], p * W, rtol=1e-12)  # the support pushes up
    assert abs(h["R_top_y"][-1]) < 1e-9 * p * W  # a loaded group is in equilibrium: no reaction
    np.testing.assert_allclose(h["R_bottom_y"], [0.5 * p * W, p * W], rtol=1e-12)  # ramped in two steps
    energy = 0.5 * p * p / e_plane * W * H
    np.testing.assert_allclose(h["E_elastic"][-1], energy, rtol=1e-12)
    np.testing.assert_allclose(h["W_external"][-1], energy, rtol=1e-12)
    assert np.abs(h["energy_error"]).max() < 1e-12 * energy
    np.testing.assert_array_equal(h["time"], [0.5, 1.0])


def test_traction_vector_and_gravity_are_consistent_loads(tmp_path):
    """A tangential traction on the top and gravity: reactions balance the applied resultants."""
    case = block(stages=[{"steps": 1, "displacement": {"bottom": {"x": 0.0, "y": 0.0}},
                          "traction": {"top": [2e5, -3e5]}, "gravity": [0.0, -9.81]}])
    case["bulk"]["density"] = 2500.0
    h = run(case, tmp_path)
    np.testing.assert_allclose(h["R_bottom_x"][-1], -2e5 * W, rtol=1e-12)
    np.testing.assert_allclose(h["R_bottom_y"][-1], 3e5 * W + 2500.0 * 9.81 * W * H, rtol=1e-12)


def test_a_released_component_springs_back(tmp_path):
    """Stage 1 shortens the block by prescribing the top; stage 2 frees it: elastic, it returns."""
    case = block(stages=[{"name": "press", "steps": 2, "displacement": {**SUPPORTS, "top": {"y": -1e-3}}},
                         {"name": "release", "steps": 1, "displacement": {"top": {"y": "free"}}}])
    h = run(case, tmp_path)
    np.testing.assert_allclose(h["u_top_y"][1], -1e-3, rtol=1e-14)
    np.testing.assert_allclose(h["R_top_y"][1], -E / (1 - NU**2) * 1e-3 / H * W, rtol=1e-12)
    assert abs(h["u_top_y"][-1]) < 1e-15 and abs(h["R_top_y"][-1]) < 1e-6
    assert list(h["stage"]) == ["press", "press", "release"]


def cohesive_block(form: str, in_situ: bool) -> dict:
    coh = dict(LAW, form=form, where="all")
    if form == "ep":
        coh.update(kn=1e13, kt=1e13)
    case = block(nx=3, ny=4, cohesive=coh,
                 stages=[{"name": "hold", "steps": 2, "displacement": SUPPORTS},
                         {"name": "push", "steps": 3, "pressure": {"top": 1e5}}])
    if in_situ:
        case["initial"] = {"stress": [{"stress": [-1e6, -2e6, -0.75e6, 0.0]}]}
    return case


@pytest.mark.parametrize("form", ["rp", "ep"])
def test_in_situ_stress_holds_still_and_shifts_the_response(tmp_path, form):
    stressed = run(cohesive_block(form, True), tmp_path, "stressed")
    free = run(cohesive_block(form, False), tmp_path, "free")
    hold = stressed["stage"] == "hold"
    assert np.all(stressed["n_plastic"] == 0)
    for col in [c for c in stressed if c.startswith("u_")]:
        assert np.abs(stressed[col][hold]).max() == 0.0, col  # nothing moves at t = 0
        np.testing.assert_allclose(stressed[col], free[col], rtol=1e-9, atol=1e-18)  # the unstressed response
    for col in [c for c in stressed if c.startswith("R_")]:
        np.testing.assert_allclose(stressed[col], free[col], rtol=1e-8, atol=1e-7 * 1e5 * W)
    points = read_csv(tmp_path / "stressed" / "points.csv")
    last = points["step"] == points["step"].max()
    n_t = np.abs(points["T_n"][last])
    assert n_t.max() <= 2e6 + 1e5 + 1.0 and n_t.min() >= 1e6 - 1.0  # the in-situ tractions carried by the cracks


def test_in_situ_gradient_balanced_by_gravity_and_refused_without(tmp_path):
    rho, g, k0 = 2500.0, 9.81, 0.5
    grad = [k0 * rho * g, rho * g, NU / (1 - NU) * rho * g, 0.0]  # d sigma / dy, compression below the top
    case = block(nx=2, ny=6, initial={"gravity": [0.0, -g], "stress": [{"stress": [0.0, 0.0, 0.0, 0.0],
                                                                         "gradient": grad, "datum": H}]},
                 stages=[{"name": "hold", "steps": 1, "displacement": SUPPORTS}])
    case["bulk"]["density"] = rho
    h = run(case, tmp_path)
    assert np.abs([h[c] for c in h if c.startswith("u_")]).max() == 0.0
    np.testing.assert_allclose(h["R_bottom_y"][-1], 0.0, atol=1e-9 * rho * g * W * H)
    bad = copy.deepcopy(case)
    del bad["initial"]["gravity"]
    with pytest.raises(CaseError, match="not in equilibrium.*gravity"):
        build(parse_case(bad, "c.toml"), "c.toml")
    nodens = copy.deepcopy(case)
    del nodens["bulk"]["density"]
    with pytest.raises(CaseError, match=r"\[initial\] gravity: region 'bulk' has no density"):
        build(parse_case(nodens, "c.toml"), "c.toml")


def test_in_situ_stress_outside_the_cohesive_strength_is_refused():
    case = cohesive_block("rp", True)
    case["initial"]["stress"][0]["stress"] = [2e6, 0.0, 0.0, 0.0]  # tension above chi_p on vertical edges
    with pytest.raises(CaseError, match="outside the traction law's yield surface"):
        build(parse_case(case, "c.toml"), "c.toml")


def test_excavation_releases_the_in_situ_traction(tmp_path):
    """Releasing the in-situ traction of the top face unloads it: the block expands elastically by
    exactly the in-situ stress's strain."""
    case = block(initial={"stress": [{"stress": [0.0, -2e6, -0.5e6, 0.0]}]},
                 stages=[{"name": "hold", "steps": 1, "displacement": SUPPORTS},
                         {"name": "excavate", "steps": 2, "in_situ": {"top": 0.0}}])
    h = run(case, tmp_path)
    np.testing.assert_allclose(h["u_top_y"][-1], 2e6 * (1 - NU**2) / E * H, rtol=1e-12)


def test_stop_rule_ends_the_program_past_the_peak(tmp_path):
    coh = dict(LAW, form="rp")
    case = {"mesh": {"crack_angle": 0.9989762274499867},
            "bulk": {"E": 1.5e7, "nu": 0.3},
            "cohesive": dict(coh, chi_p=15680.0, c_p=9053.0, phi_p=0.5236, psi_p=0.087),
            "stages": [{"name": "confine", "displacement": {"bottom": {"y": 0.0}, "bottom_left": {"x": 0.0},
                                                               "top": {"y": 0.0}},
                        "pressure": {"left": 2e4, "right": 2e4}},
                       {"name": "shorten", "steps": 200, "control": "path",
                        "displacement": {"top": {"y": -4e-3}},
                        "stop": {"quantity": "R_top_y", "below_peak_fraction": 0.6}}],
            "output": {"picture": False}}
    h = run(case, tmp_path)
    r = np.abs(h["R_top_y"])
    assert r[-1] < 0.6 * r.max() <= r[-2]
    assert "fell below 0.6" in (tmp_path / "o" / "run.log").read_text()


@pytest.mark.parametrize("edit,expected", [
    ({"displacement": {"lid": {"y": 0.0}}}, r"\[stages 1\] displacement: node group 'lid' not in the mesh"),
    ({"displacement": {"top": {"z": 0.0}}}, r"\[stages 1\] displacement.top.z: a 2D mesh has components x, y"),
    ({"pressure": {"rim": 1.0}}, r"\[stages 1\] pressure: boundary group 'rim' not in the mesh"),
    ({"traction": {"right": [1.0, 2.0, 3.0]}}, r"\[stages 1\] traction.right: 3 components; this 2D mesh needs 2"),
    ({"gravity": [0.0, -9.81]}, r"\[stages 1\] gravity: region 'bulk' has no density"),
    ({"in_situ": {"top": 0.0}}, r"\[stages 1\] in_situ: there is no in-situ stress"),
    ({"control": "path"}, r"control = 'path' follows a crack jump"),
    ({"stop": {"quantity": "R_lid_y", "below_peak_fraction": 0.5}}, r"stop.quantity: 'R_lid_y' is not a history"),
])
def test_bad_stages_name_the_stage_and_key(tmp_path, edit, expected):
    case = block()
    case["stages"][0].update(edit)
    with pytest.raises(CaseError, match=expected):
        run_case(parse_case(case, "c.toml"), tmp_path / "o", path_label="c.toml")
    assert not (tmp_path / "o" / "history.csv").exists()


def test_resume_of_a_program_with_in_situ_stress_is_bit_for_bit(tmp_path):
    """The paper's RP specimen confined by an in-situ stress instead of a confinement stage, sheared
    past its peak under path control, cut and resumed."""
    case = {"mesh": {"crack_angle": 0.9989762274499867}, "bulk": {"E": 1.5e7, "nu": 0.3},
            "cohesive": dict(LAW, form="rp", chi_p=15680.0, c_p=9053.0, phi_p=0.5236, psi_p=0.087),
            "initial": {"stress": [{"stress": [-2e4, -2e4, -2e4, 0.0]}]},
            "stages": [{"name": "hold", "displacement": {"bottom": {"y": 0.0}, "bottom_left": {"x": 0.0},
                                                          "top": {"y": 0.0}}},
                       {"name": "shorten", "steps": 40, "control": "path", "displacement": {"top": {"y": -1.5e-3}}}],
            "output": {"picture": False, "checkpoint_every": 10}}
    full = run(case, tmp_path, "full")
    assert full["n_plastic"].max() > 0 and full["n_plastic"][0] == 0
    c = parse_case(case)

    class Cut(Exception):
        pass

    def stop(row):
        if row["step"] == 27:
            raise Cut

    with pytest.raises(Cut):
        run_case(c, tmp_path / "cut", progress=stop)
    run_case(c, tmp_path / "cut", resume=True)
    cut = read_csv(tmp_path / "cut" / "history.csv")
    assert len(cut["step"]) == len(full["step"])
    for k in full:
        if full[k].dtype.kind == "f":
            np.testing.assert_array_equal(full[k], cut[k])


def test_api_keeps_the_fields_of_the_steps_asked_for(tmp_path):
    import rockfrac as rf

    case = rf.make_case(block(stages=[{"name": "load", "steps": 4, "displacement": SUPPORTS,
                                       "pressure": {"top": 1e6}}]))
    r = rf.run(case, tmp_path / "every", fields_every=1)
    assert sorted(r.snapshots) == [1, 2, 3, 4]
    for k in range(1, 5):  # the ramp: sigma_yy = -p k / 4 in every cell, u_y at the top likewise
        np.testing.assert_allclose(r.cell_stress(step=k)[:, 1], -1e6 * k / 4, rtol=1e-12)
        top = r.built.mesh.node_sets["top"]
        np.testing.assert_allclose(r.displacement(step=k)[top, 1], r.history["u_top_y"][k - 1], rtol=1e-12)
    np.testing.assert_array_equal(r.cell_stress(step=4), r.cell_stress())
    r2 = rf.run(case, tmp_path / "two", fields_every=2)
    assert sorted(r2.snapshots) == [2, 4]
    with pytest.raises(KeyError, match=r"step 3: its fields were not kept; kept: steps 2..4 every 2"):
        r2.displacement(step=3)
    with pytest.raises(KeyError, match="run with fields_every"):
        rf.run(case, tmp_path / "none").cell_stress(step=1)
    with pytest.raises(CaseError, match="fields_every = -1: a whole number"):
        rf.run(case, tmp_path / "bad", fields_every=-1)


@pytest.mark.parametrize("pin", ["bottom_left", "bottom"])
def test_a_loading_pin_on_the_support_holds_it_in_x_and_y(pin):
    """[loading] pin = support (a base held in x and y) holds both components of every base node; it
    used to replace the support's y (the group was a key twice), leaving the base free to move."""
    d = {"mesh": {"kind": "block", "width": W, "height": H, "nx": 2, "ny": 4}, "bulk": {"E": E, "nu": NU},
         "loading": {"confinement": 1e5, "axial_displacement": 1e-4, "axial_steps": 1, "pin": pin},
         "output": {"picture": False}}
    built = build(parse_case(d, "c.toml"))
    bottom, corner = built.mesh.node_sets["bottom"], built.mesh.node_sets["bottom_left"]
    held = set(built.stages[0].dirichlet.tolist())
    assert set((2 * bottom + 1).tolist()) <= held  # the support, whatever the pin
    assert (set((2 * bottom).tolist()) <= held) == (pin == "bottom")
    assert set((2 * corner).tolist()) <= held
