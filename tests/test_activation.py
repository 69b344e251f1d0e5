"""The first activation of a cohesive surface ends a load step: peaks are steps, at the closed-form
activation load (issue 15), and a surface that starts from a located activation keeps its
integration order (tests/test_cse_opening_and_newton.py)."""

from __future__ import annotations

import math
import tomllib
from pathlib import Path

import numpy as np
import pytest
from conftest import P, THETA, TABLE1, W, paper_case

from rockfrac import analytic
from rockfrac.case.schema import parse_case
from rockfrac.output.csvout import read_csv
from rockfrac.runner import run_case

ROOT = Path(__file__).resolve().parents[1]


def activation_force() -> float:
    """Axial force at which the paper's crack plane reaches F = 0 with the peak strengths [N/m]."""
    return analytic.strength_force(P, THETA, TABLE1["chi_p"], TABLE1["c_p"], math.tan(TABLE1["phi_p"]), W)


@pytest.mark.parametrize("form,k", [("rp", None), ("ep", 1e9), ("ep", 1e8)])
def test_paper_cases_peak_at_the_closed_form_activation(run, form, k):
    case = paper_case(form, k, axial_displacement=1.5e-3, axial_steps=60, control="path")
    h, _, s = run(case, "located")
    assert s.result.completed, s.result.message
    first = int(np.flatnonzero(h["n_plastic"] > 0)[0])
    landing = first - 1  # the step that ends at the activation: nothing has yielded yet
    assert h["n_plastic"][landing] == 0
    assert h["F_axial"][landing] == pytest.approx(activation_force(), rel=1e-6)
    assert h["F_axial"].max() <= h["F_axial"][landing] * (1 + 1e-9)  # it is the peak
    # stepped over (the paper's stepping), the peak is well below it
    case["solver"] = {"locate_activation": False}
    g, _, _ = run(case, "over")
    assert g["F_axial"].max() < (1 - 2e-3) * activation_force()


def test_snap_back_bar_peaks_at_the_strength(tmp_path):
    data = tomllib.loads((ROOT / "examples" / "path_following" / "bar_snapback.toml").read_text())
    data["loading"]["axial_steps"] = 100
    s = run_case(parse_case(data, "bar"), tmp_path / "o")
    h = read_csv(tmp_path / "o" / "history.csv")
    assert s.result.completed, s.result.message
    peak = data["cohesive"]["chi_p"] * data["mesh"]["width"]
    landing = int(np.flatnonzero(h["n_plastic"] > 0)[0]) - 1
    assert -h["F_axial"][landing] == pytest.approx(peak, rel=1e-6)  # tension: F_axial < 0
    assert (-h["F_axial"]).max() == pytest.approx(peak, rel=1e-9)
    assert "a surface first yields" in (tmp_path / "o" / "run.log").read_text()


def test_the_landing_needs_no_retry_and_is_skipped_once_yielded(tmp_path):
    """The step is ended at the activation by one prediction (elastic bulk: exact), and the
    prediction stops once the surface has yielded: one landing in the log."""
    case = paper_case("rp", axial_displacement=1e-3, axial_steps=20)
    run_case(parse_case(case, "c"), tmp_path / "o")
    log = (tmp_path / "o" / "run.log").read_text()
    assert log.count("a surface first yields") == 1
    landing = log.split("a surface first yields")[1].split("\nstep ")[0]  # until the step is logged done
    # no retry; converged at once (elastic bulk) or, where round-off puts the point just outside its
    # yield surface (it sits on it by construction), after one active-set switch
    assert "cutting back" not in landing and " it 3:" not in landing
