"""Path following through a snap-back against the closed form of a long bar with an RP crack."""

import math
from pathlib import Path

import numpy as np
import pytest

from rockfrac.case.schema import load_case
from rockfrac.output.csvout import read_csv
from rockfrac.runner import run_case
from rockfrac.studies import table1

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "path_following" / "bar_snapback.toml"


def traced(tmp_path, increment):
    case = load_case(EXAMPLE)
    case = case.model_copy(update={"loading": case.loading.model_copy(update={"path_increment": increment})})
    s = run_case(case, tmp_path / f"{increment:g}")
    assert s.result.completed, s.result.message
    h = read_csv(tmp_path / f"{increment:g}" / "history.csv")
    return case, h


def test_traced_path_follows_the_closed_form_through_the_snap_back(tmp_path):
    errors = []
    for inc in (4e-5, 2e-5):
        case, h = traced(tmp_path, inc)
        c, b = case.cohesive_sets[0], case.bulk
        e1 = b.E / (1 - b.nu**2)
        big_l = case.mesh.height
        sigma = -h["F_axial"] / case.mesh.width  # tension
        u = -h["u_axial"]
        pl = h["n_plastic"] > 0
        assert pl.sum() > 50
        closed = sigma[pl] * big_l / e1 + (c.chi_p / sigma[pl] - 1) * c.GfI / (c.alpha_chi * c.chi_p)
        errors.append(np.max(np.abs(u[pl] - closed)) / np.max(u))
        # the snap-back is there and is traced down to the closed form's turning point
        assert big_l / e1 > c.GfI / (c.alpha_chi * c.chi_p**2)
        s_star = math.sqrt(c.GfI * e1 / (c.alpha_chi * big_l))
        u_star = s_star * big_l / e1 + (c.chi_p / s_star - 1) * c.GfI / (c.alpha_chi * c.chi_p)
        assert np.any(np.diff(u[pl]) < 0)
        assert u[pl].min() == pytest.approx(u_star, rel=1e-2)
        assert u[pl].min() < 0.98 * c.chi_p * big_l / e1  # well below the displacement at the peak
    assert errors[1] < 0.006
    assert 1.6 < errors[0] / errors[1] < 2.4  # backward Euler: first order in the increment


def test_penalty_study_errors_fall_with_k_and_the_rule_of_thumb(tmp_path):
    """Slope error: monotone in k, equal to the series-compliance closed form, ~ E'/(k L); ISV
    histories of EP and RP agree for large k; a penalty below the softening slope is flagged."""
    from rockfrac.studies.penalty import run_penalty_study

    rows = run_penalty_study(tmp_path, axial_steps=150)
    ok = [r for r in rows if not r.note]
    assert [r.k for r in rows if r.note] == [1e7] and "softening slope" in rows[0].note
    slope = [r.slope_error for r in ok]
    assert all(b < a for a, b in zip(slope, slope[1:]))
    for r in ok:
        assert r.slope_error == pytest.approx(r.slope_error_closed_form, rel=1e-3)
        assert r.slope_error < 1.0 / r.k_l_over_e  # the rule of thumb bounds it for every k
        if r.k_l_over_e > 40:  # small-compliance regime: error -> cos(theta) E'/(k L), cos(theta) = 0.54
            assert r.slope_error * r.k_l_over_e == pytest.approx(math.cos(table1.CRACK_ANGLE), rel=0.1)
        assert r.dissipation_error < 0.05 / r.k_l_over_e
    assert all(r.isv_difference < 1e-3 for r in ok if r.k >= 1e10)
    assert (tmp_path / "penalty.png").stat().st_size > 20_000
    assert "k L / E' >= 1/eps" in (tmp_path / "penalty.md").read_text()


def test_run_warns_about_a_soft_penalty(tmp_path, capsys):
    from rockfrac.cli import main

    ex = Path(__file__).resolve().parents[1] / "examples" / "paper"
    text = (ex / "cse_ep_k1e8.toml").read_text().replace("axial_steps = 400", "axial_steps = 10")
    case = tmp_path / "c.toml"
    case.write_text(text)
    assert main(["run", str(case), "--out", str(tmp_path / "o"), "--quiet"]) == 0
    err = " ".join(capsys.readouterr().err.split())
    assert "warning: EP CSE penalty kn, kt = 1e+08" in err and "k >= 2.06e+10 Pa/m" in err
    assert "warning" in (tmp_path / "o" / "run.log").read_text()
    text = text.replace("kn = 1e8", "kn = 1e11").replace("kt = 1e8", "kt = 1e11")
    case.write_text(text)
    assert main(["run", str(case), "--out", str(tmp_path / "o2"), "--quiet"]) == 0
    assert "warning" not in capsys.readouterr().err
