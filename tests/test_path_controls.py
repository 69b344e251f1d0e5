"""Stage controls beyond the load factor: an opening between two points (CMOD), the arc length and
the energy released, against closed forms, through peaks and snap-backs; their checkpoints resume bit for bit; their
inputs are checked."""

from __future__ import annotations

import math
import tomllib
from pathlib import Path

import numpy as np
import pytest

from rockfrac.case.schema import CaseError, parse_case
from rockfrac.output.csvout import read_csv
from rockfrac.runner import run_case

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def data_of(name: str) -> dict:
    data = tomllib.loads((EXAMPLES / name).read_text())
    if data["mesh"].get("file"):
        data["mesh"]["file"] = str((EXAMPLES / name).parent / data["mesh"]["file"])
    return data


def run(data: dict, out: Path, **kw):
    s = run_case(parse_case(data, "<test>"), out, **kw)
    return s, read_csv(out / "history.csv")


def bar_closed_form(data: dict, sigma: np.ndarray) -> np.ndarray:
    """Top displacement of the bar with a pure-opening crack at tension sigma (bar_snapback.toml)."""
    c, b = data["cohesive"], data["bulk"]
    e1 = b["E"] / (1 - b["nu"] ** 2)
    return sigma * data["mesh"]["height"] / e1 + (c["chi_p"] / sigma - 1) * c["GfI"] / (c["alpha_chi"] * c["chi_p"])


def test_opening_control_traces_the_snap_back_of_the_bar(tmp_path):
    data = data_of("path_following/bar_opening.toml")
    s, h = run(data, tmp_path / "o")
    assert s.result.completed, s.result.message
    c, b, big_l, width = data["cohesive"], data["bulk"], data["mesh"]["height"], data["mesh"]["width"]
    sigma, u, opening = h["R_top_y"] / width, h["u_top_y"], h["crack_opening"]
    pl = h["n_plastic"] > 0
    rigid = ~pl
    # while the crack is rigid the opening cannot move: each step is a load step of 1/steps
    assert rigid.sum() > 40 and np.all(opening[rigid] == pytest.approx(0.0, abs=1e-15))
    lam = h["load_factor"]
    rigid_steps = np.diff(lam[rigid])
    np.testing.assert_allclose(rigid_steps[:-1], 1.0 / data["stages"][0]["steps"], rtol=1e-9)
    # the path step in which the crack first yields is ended where it does: its peak is a step, at the
    # strength times the width (to 1e-5: the one-cell-wide bar's crack points carry a shear of 0.2 % of it)
    assert 0.0 < rigid_steps[-1] < 1.0 / data["stages"][0]["steps"]
    assert h["control"][rigid][-1] == "load" and np.flatnonzero(rigid)[-1] == np.flatnonzero(pl)[0] - 1
    assert h["R_top_y"][rigid][-1] == pytest.approx(c["chi_p"] * width, rel=1e-5)
    assert h["R_top_y"].max() <= h["R_top_y"][rigid][-1] * (1 + 1e-9)
    # once open, every step prescribes exactly the increment of opening (the last lands on lam = 1)
    np.testing.assert_allclose(np.diff(opening[pl])[:-1], data["stages"][0]["path_increment"], rtol=1e-7)
    # the closed form through the snap-back, down to its turning point
    assert np.max(np.abs(u[pl] - bar_closed_form(data, sigma[pl]))) < 0.006 * u.max()
    e1 = b["E"] / (1 - b["nu"] ** 2)
    s_star = math.sqrt(c["GfI"] * e1 / (c["alpha_chi"] * big_l))
    assert np.any(np.diff(u[pl]) < 0)
    assert u[pl].min() == pytest.approx(float(bar_closed_form(data, np.array(s_star))), rel=1e-2)
    assert lam[-1] == 1.0  # the stage ends on its end values


def test_arc_length_passes_the_peak_of_a_force_controlled_bar(tmp_path):
    data = data_of("path_following/bar_arc_length.toml")
    stage = data["stages"][0]
    chi, end = data["cohesive"]["chi_p"], stage["traction"]["top"][1]
    # load control stops at the peak: the crack's strength over the traction's end value
    load = {**data, "stages": [{k: v for k, v in stage.items() if k not in ("control", "max_steps")}]}
    s, h = run(load, tmp_path / "load")
    assert not s.result.completed and "min_step" in s.result.message
    nominal = 1.0 / stage["steps"]  # it cuts back to 1e-4 of it (min_step) below the peak
    assert chi / end - 2e-4 * nominal < h["load_factor"][-1] <= chi / end
    # the arc length goes over it and down the softening branch to the stop
    s, h = run(data, tmp_path / "arc")
    assert s.result.completed and "fell below 0.3" in s.result.message
    later = list(h["control"][1:])  # path steps, but for the one that ends where the crack first yields
    assert h["control"][0] == "load" and later.count("load") == 1 and set(later) == {"path", "load"}
    sigma, u = h["load_factor"] * end, h["u_top_y"]
    assert h["load_factor"].max() <= chi / end * (1 + 1e-9)
    # the path step that first yields is ended where the crack activates: the peak is a step, on the closed form
    landing = int(np.flatnonzero(h["n_plastic"] > 0)[0]) - 1
    assert h["control"][landing] == "load" and h["load_factor"][landing] == pytest.approx(chi / end, rel=1e-7)
    assert h["load_factor"].max() == h["load_factor"][landing]
    pl = h["n_plastic"] > 0
    assert pl.sum() > 100 and np.all(np.diff(u) > 0)  # no snap-back in this bar: u grows all along
    assert sigma[-1] < 0.31 * chi
    np.testing.assert_allclose(-h["R_bottom_y"] / data["mesh"]["width"], sigma, rtol=1e-8)
    assert np.max(np.abs(u[pl] - bar_closed_form(data, sigma[pl]))) < 0.003 * u.max()
    assert np.abs(h["energy_error"]).max() < 1e-9 * h["W_external"].max()


def test_arc_length_of_an_elastic_bar_takes_equal_steps_to_the_stage_end(tmp_path):
    """Linear response: the path is straight, so the constraint t . du = ds makes every step the
    first one's size: the load factor moves by 1/steps each step and lands on 1."""
    data = data_of("path_following/bar_arc_length.toml")
    data.pop("cohesive")
    data["mesh"]["crack"] = False
    data["mesh"].pop("crack_angle")
    stage = data["stages"][0]
    stage.pop("stop")
    s, h = run(data, tmp_path / "o")
    assert s.result.completed and s.result.steps == stage["steps"]
    np.testing.assert_allclose(np.diff(h["load_factor"]), 1.0 / stage["steps"], rtol=1e-9)
    assert h["load_factor"][-1] == 1.0


def test_energy_control_traces_the_snap_back_of_a_force_loaded_bar(tmp_path):
    data = data_of("path_following/bar_energy.toml")
    stage = data["stages"][0]
    s, h = run(data, tmp_path / "o")
    assert s.result.completed and "fell below 0.3" in s.result.message
    c, b, big_l = data["cohesive"], data["bulk"], data["mesh"]["height"]
    end = stage["traction"]["top"][1]
    lam, u = h["load_factor"], h["u_top_y"]
    sigma = lam * end
    pl = h["n_plastic"] > 0
    # load steps until the crack yields, then every step releases exactly the increment:
    # [(f_n - f_0) . u - (f - f_0) . u_n] / 2 with f = lam x (the traction's nodal forces); the top
    # moves as one, so f . u = lam end width u_top
    assert set(h["control"][~pl]) == {"load"} and set(h["control"][pl][1:]) == {"path"}
    force = end * data["mesh"]["width"]
    released = 0.5 * force * (lam[:-1] * u[1:] - lam[1:] * u[:-1])
    path = h["control"][1:] == "path"
    np.testing.assert_allclose(released[path], stage["path_increment"], rtol=1e-6)
    # through the snap-back (neither load nor arc-length control follows it) on the closed form
    assert np.max(np.abs(u[pl] - bar_closed_form(data, sigma[pl]))) < 0.006 * u.max()
    e1 = b["E"] / (1 - b["nu"] ** 2)
    s_star = math.sqrt(c["GfI"] * e1 / (c["alpha_chi"] * big_l))
    assert np.any(np.diff(u[pl]) < 0)
    assert u[pl].min() == pytest.approx(float(bar_closed_form(data, np.array(s_star))), rel=1e-2)
    assert np.abs(h["energy_error"]).max() < 1e-9 * h["W_external"].max()


def test_energy_released_is_zero_on_an_elastic_path_from_a_prestressed_state():
    """g = [(f_n - f_0) . (u - u_0) - (f - f_0) . (u_n - u_0)] / 2 vanishes on any two states of a
    linear body f = f_0 + K (u - u_0) (K symmetric), whatever the initial state (in-situ forces f_0,
    displacements u_0); it is the secant dissipation of a damaged one."""
    from rockfrac.solve.newton import Loads
    from rockfrac.solve.paths import Committed, energy_path

    rng = np.random.default_rng(3)
    n = 6
    m = rng.normal(size=(n, n))
    k = m @ m.T + n * np.eye(n)
    u_ref, f_ref = rng.normal(size=n), rng.normal(size=n)
    f0, df = f_ref + rng.normal(size=n), rng.normal(size=n)
    loads = Loads(np.zeros(0), np.zeros(0), f0, df)

    def state(lam, stiffness):
        return u_ref + np.linalg.solve(stiffness, loads.forces(lam) - f_ref)

    spec = energy_path(n, 2.0, 1.0, lambda: True, 10)
    c = spec.constraint(Committed(state(0.3, k), None, 0.3, loads, u_ref, f_ref))
    assert c is not None
    for lam in (0.1, 0.5, 2.0):
        assert abs(c.value(state(lam, k), lam)) < 1e-12 * np.abs(f0).max() * np.abs(state(lam, k)).max()
        # its gradients are those of the formula
        du = rng.normal(size=n) * 1e-3
        g0 = c.value(state(lam, k), lam)
        assert c.value(state(lam, k) + du, lam + 1e-3) - g0 == pytest.approx(
            float(c.measure(state(lam, k))[1] @ du) + c.lam_coeff * 1e-3, rel=1e-9)
    # a body that softened to half its stiffness releases, from lam_n on the secant, the energy
    # between the two secants: (f_n - f_ref) . (K_s^-1 - K^-1) (f_n - f_ref) / 4 at lam = lam_n
    lam = 0.3
    u_soft = state(lam, 0.5 * k)
    df_n = loads.forces(lam) - f_ref
    expected = 0.25 * df_n @ (np.linalg.solve(0.5 * k, df_n) - np.linalg.solve(k, df_n))
    assert c.value(u_soft, lam) == pytest.approx(expected, rel=1e-10)


def test_cmod_controlled_beam_dissipates_gc_times_the_ligament(tmp_path):
    from rockfrac.mesh import rock_tests as rt

    data = data_of("rock_tests/bending/notched_beam_cmod.toml")
    data["mesh"]["file"] = str(rt.notched_beam(tmp_path / "beam.msh", element_size=0.005))
    data["stages"][0]["path_increment"] = 2e-6
    s, h = run(data, tmp_path / "o")
    assert s.result.completed and "fell below 0.005" in s.result.message
    np.testing.assert_allclose(np.diff(h["cmod"])[1:], 2e-6, rtol=1e-7)
    gc_l = data["cohesive"]["Gc"] * 0.035
    ratio = h["D_dissipated"][-1] / gc_l
    tail = abs(h["R_load_y"][-1] * h["u_load_y"][-1]) / gc_l
    assert 0.9 < ratio < 1.0 and abs(ratio + tail - 1.0) < 0.05  # 5 mm elements (0.011 at 2.5 mm)
    assert np.abs(h["energy_error"]).max() < 1e-9 * h["W_external"][-1]
    # the same beam under deflection control: the same curve (load against deflection)
    dc = data_of("rock_tests/bending/notched_beam_cmod.toml")
    dc["mesh"]["file"] = data["mesh"]["file"]
    st = dc["stages"][0]
    for k in ("control", "monitor", "path_increment", "max_steps"):
        st.pop(k)
    st["steps"] = 500
    _, g = run(dc, tmp_path / "d")
    assert abs(h["R_load_y"]).max() == pytest.approx(abs(g["R_load_y"]).max(), rel=0.01)
    d, p = -g["u_load_y"], -g["R_load_y"]
    on = -h["u_load_y"] < d[-1]
    np.testing.assert_allclose(-h["R_load_y"][on], np.interp(-h["u_load_y"][on], d, p), atol=0.02 * p.max())


def test_arc_length_checkpoint_resumes_bit_for_bit(tmp_path):
    class Interrupt(Exception):
        pass

    data = data_of("path_following/bar_arc_length.toml")
    data["output"] = {"checkpoint_every": 40, "picture": False}
    case = parse_case(data, "<test>")
    run_case(case, tmp_path / "full")

    def stop(row):
        if row["step"] == 130:
            raise Interrupt()

    with pytest.raises(Interrupt):
        run_case(case, tmp_path / "cut", progress=stop)
    s = run_case(case, tmp_path / "cut", resume=True)
    assert s.result.completed
    a, b = read_csv(tmp_path / "full" / "history.csv"), read_csv(tmp_path / "cut" / "history.csv")
    assert len(a["step"]) == len(b["step"])
    for k in a:
        if a[k].dtype.kind == "f":
            np.testing.assert_array_equal(a[k], b[k])
    assert "resumed from the checkpoint at step 120" in (tmp_path / "cut" / "run.log").read_text()


@pytest.mark.parametrize("change, message", [
    ({"monitor": None}, "control = 'opening' takes monitor"),
    ({"monitor": "nowhere"}, "monitor = 'nowhere': not an opening monitor of [[monitors]] (openings: crack_opening)"),
    ({"monitor": "top_point"}, "monitor = 'top_point': not an opening monitor"),
    ({"control": "load", "path_increment": None, "max_steps": None}, "control = 'opening' takes monitor"),
    ({"control": "load", "monitor": None}, "path_increment, max_steps only apply to control = 'path', "
                                           "'opening', 'arc_length' or 'energy'"),
    ({"control": "arc"}, "control"),
    ({"control": "energy", "monitor": None}, "control = 'energy': the stage moves prescribed displacements"),
    ({"control": "energy", "monitor": None, "path_increment": None}, "path_increment: control = 'energy' needs the "
                                                                      "energy released per step"),
])
def test_bad_control_inputs_are_named(tmp_path, change, message):
    data = data_of("path_following/bar_opening.toml")
    data["monitors"].append({"name": "top_point", "kind": "displacement", "at": [0.0, 1.0]})
    stage = data["stages"][0]
    for k, v in change.items():
        if v is None:
            stage.pop(k, None)
        else:
            stage[k] = v
    with pytest.raises(CaseError) as err:
        run_case(parse_case(data, "bar.toml"), tmp_path / "o", path_label="bar.toml")
    text = " ".join(str(err.value).split())
    assert message in text and "bar.toml" in text
    assert not (tmp_path / "o" / "history.csv").exists()
