"""Stage controls beyond the load factor: an opening between two points (CMOD) and the arc length,
against closed forms, through peaks and snap-backs; their checkpoints resume bit for bit; their
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
    np.testing.assert_allclose(np.diff(lam[rigid]), 1.0 / data["stages"][0]["steps"], rtol=1e-9)
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
    assert h["control"][0] == "load" and set(h["control"][1:]) == {"path"}
    sigma, u = h["load_factor"] * end, h["u_top_y"]
    assert h["load_factor"].max() <= chi / end * (1 + 1e-9)
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
                                           "'opening' or 'arc_length'"),
    ({"control": "arc"}, "control"),
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
