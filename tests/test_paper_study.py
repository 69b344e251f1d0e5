"""``rockfrac paper`` end to end on a small step count, the paper's claims on its CSVs; the example
files equal the study's cases."""

import math
from pathlib import Path

import numpy as np
import pytest

from rockfrac import analytic
from rockfrac.case.schema import load_case, parse_case
from rockfrac.cli import main
from rockfrac.output.csvout import read_csv
from rockfrac.studies import paper, table1

ROOT = Path(__file__).resolve().parents[1]
CASES = {"cse_ep_k1e9": paper.EP9, "cse_ep_k1e8": paper.EP8, "cse_rp": paper.RP, "ede": paper.EDE}


@pytest.mark.parametrize("name,key", list(CASES.items()))
def test_example_case_files_are_the_study_cases(name, key):
    example = load_case(ROOT / "examples" / "paper" / f"{name}.toml")
    study = parse_case(paper.study_cases(1200 if key == paper.EDE else 400)[key])
    sections = ("mesh", "bulk", "cohesive", "embedded")
    for section in sections:
        assert getattr(example, section) == getattr(study, section), section
    assert example.loading.confinement == study.loading.confinement


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    out = tmp_path_factory.mktemp("paper")
    assert main(["paper", "--out", str(out), "--steps", "100", "--quiet"]) == 0
    return out


def history(out, name):
    folder = name.replace(" ", "_").replace("=", "").replace(",", "")
    return read_csv(out / "cases" / folder / "history.csv")


def test_every_figure_and_its_csv_is_written(study):
    for stem in ("fig5_force_displacement", "fig6_deformed_meshes", "fig7_cohesion", "fig8_friction",
                 "fig9_dilation", "fig5b_unreduced_rates"):
        assert (study / f"{stem}.png").stat().st_size > 20_000  # a real plot, not an empty canvas
        data = read_csv(study / f"{stem}.csv")
        assert len(data["case"]) > 50
    assert set(read_csv(study / "fig5_force_displacement.csv")["case"]) == set(paper.PAPER_CASES)
    mesh = read_csv(study / "fig6_deformed_meshes.csv")
    assert {"crack_minus", "crack_plus", "deformed", "undeformed"} <= set(mesh["line"][mesh["case"] == paper.EDE])
    report = (study / "report.md").read_text()
    for text in ("Table 1 as used", "Key numbers", "claims, checked", "fig6_deformed_meshes.png", "9053"):
        assert text in report


def test_the_papers_claims_hold_on_the_csvs(study):
    rp, ep9, ep8, ede = (history(study, k) for k in (paper.RP, paper.EP9, paper.EP8, paper.EDE))
    # RP CSE on the uncracked elastic curve until activation
    pre = (rp["n_plastic"] == 0) & (rp["stage"] == "axial")
    elastic = [analytic.elastic_force(u, 2e4, 1.5e7, 0.3, 0.04, 0.08) for u in rp["u_axial"][pre]]
    np.testing.assert_allclose(rp["F_axial"][pre], elastic, rtol=1e-10)
    # EP 1e9 close to RP; EP 1e8 visibly softer before the peak
    u = np.linspace(1.0e-3, 4.0e-3, 20)  # through the softening branch
    ax9, axr = ep9["stage"] == "axial", rp["stage"] == "axial"
    np.testing.assert_allclose(np.interp(u, ep9["u_axial"][ax9], ep9["F_axial"][ax9]),
                               np.interp(u, rp["u_axial"][axr], rp["F_axial"][axr]), rtol=0.02)
    s_rp, s9, s8 = (paper._pre_peak_slope(h) for h in (rp, ep9, ep8))
    assert 0.85 < s9 / s_rp < 0.95 and s8 / s_rp < 0.6
    # EDE: rises after yield, bifurcates near 3700 N/m, softens to the residual p W
    plastic = ede["bulk_plastic"] > 0
    f_yield = ede["F_axial"][np.flatnonzero(plastic)[0] - 1]
    onset = np.flatnonzero(ede["n_localized"] > 0)[0]
    assert ede["F_axial"].max() > 1.1 * f_yield
    assert 3550 < ede["F_axial"][onset] < 3750
    assert ede["F_axial"][-1] == pytest.approx(800.0, rel=0.02)
    # EP and RP: same ISV histories versus ||[u^p]||
    c = read_csv(study / "fig7_cohesion.csv")
    grid = np.linspace(4e-4, 3e-3, 30)  # past the first (sparse, coarse-step) plastic samples
    a = np.interp(grid, c["jump_p_norm"][c["case"] == paper.RP], c["c"][c["case"] == paper.RP])
    b = np.interp(grid, c["jump_p_norm"][c["case"] == paper.EP9], c["c"][c["case"] == paper.EP9])
    assert np.abs(a - b).max() < 5e-3 * table1.CSE_LAW["c_p"]


def test_beyond_the_paper_unreduced_rates_complete_through_a_snap_back(study):
    h = history(study, paper.BEYOND)
    assert h["u_axial"][-1] == pytest.approx(4e-3, rel=1e-9)
    path = h["control"] == "path"
    assert path.sum() > 20 and np.any(np.diff(h["u_axial"][path]) < 0)
    # the softening branch obeys the closed form of the current strengths, as for the paper's cases
    pl = h["n_plastic"] > 0
    allowed = [analytic.strength_force(2e4, table1.CRACK_ANGLE, chi, cc, tp, 0.04)
               for chi, cc, tp in zip(h["chi"][pl], h["c"][pl], h["tan_phi"][pl])]
    np.testing.assert_allclose(h["F_axial"][pl], allowed, rtol=1e-7)
    assert math.isclose(h["F_axial"][-1], history(study, paper.RP)["F_axial"][-1], rel_tol=0.05)


def test_the_study_history_is_the_reference_to_round_off(study):
    """The study at 100 steps against the same study run by the first version's code (commit 67d4aa8,
    bit for bit the paper study of the original engine; tests/data/paper_steps100_history.csv):
    the same steps, forces and displacements to 1e-9 of the case's peak force / final displacement.
    Round-off may move a Newton iteration from one step to the next where a residual sits at the
    tolerance (the linear solver's bits depend on the process's thread pools): per case the total
    may not change by more than 1 %."""
    import csv

    with open(ROOT / "tests" / "data" / "paper_steps100_history.csv") as f:
        ref = list(csv.DictReader(f))
    for name in (paper.EDE, paper.EP9, paper.EP8, paper.RP, paper.BEYOND):
        rows = [r for r in ref if r["case"] == name]
        h = history(study, name)
        assert len(h["step"]) == len(rows), name
        u = np.array([float(r["u_axial"]) for r in rows])
        f_ref = np.array([float(r["F_axial"]) for r in rows])
        assert np.abs(h["u_axial"] - u).max() <= 1e-9 * np.abs(u).max(), name
        assert np.abs(h["F_axial"] - f_ref).max() <= 1e-9 * np.abs(f_ref).max(), name
        its = sum(int(r["newton_iterations"]) for r in rows)
        assert abs(h["newton_iterations"].sum() - its) <= 0.01 * its, name


def test_cases_in_worker_processes_give_the_same_bits_as_one_process(study, tmp_path):
    """The fixture ran the study on two worker processes (the default on this machine); one process,
    one case after the other, writes the same CSVs to the last bit."""
    import os

    if (os.cpu_count() or 1) < 2:
        pytest.skip("one core: the default is one process")
    assert main(["paper", "--out", str(tmp_path), "--steps", "100", "--quiet", "--jobs", "1"]) == 0
    files = sorted(p.relative_to(study) for p in study.rglob("*.csv"))
    assert len(files) >= 15 and files == sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*.csv"))
    for f in files:
        assert (study / f).read_bytes() == (tmp_path / f).read_bytes(), f


def test_jobs_must_be_a_whole_number_of_processes(capsys):
    for bad in ("0", "x", "65"):
        assert main(["paper", "--out", "unused", "--jobs", bad]) == 2  # argparse's usage error
        assert "processes" in capsys.readouterr().err


def test_a_coarse_study_completes_and_says_what_it_cannot_measure(tmp_path):
    """At 10 steps the CSE cases yield in their first axial step: no elastic points for the
    pre-peak slope, which the report says instead of failing."""
    assert main(["paper", "--out", str(tmp_path), "--steps", "10", "--quiet", "--jobs", "1"]) == 0
    report = (tmp_path / "report.md").read_text()
    assert "not measurable at this step count" in report and "nan" not in report.split("## Figures")[0].lower()


def test_a_fresh_process_forks_its_workers_and_writes_the_one_process_bits(study, tmp_path):
    """`rockfrac paper` as a user starts it (a fresh process, a progress display): the workers are
    forked (nothing to import again) and the CSVs are those of one process to the last bit."""
    import os
    import subprocess
    import sys

    if (os.cpu_count() or 1) < 2 or not sys.platform.startswith("linux"):
        pytest.skip("one core or not Linux: no forked workers")
    out = tmp_path / "forked"
    run = subprocess.run([sys.executable, "-m", "rockfrac.cli", "paper", "--out", str(out), "--steps", "100",
                          "--jobs", "2"], capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stderr[-2000:]
    assert "the cases on 2 worker processes (fork)" in (out / "report.md").read_text()
    one = tmp_path / "one"
    assert main(["paper", "--out", str(one), "--steps", "100", "--quiet", "--jobs", "1"]) == 0
    assert "the cases in one process" in (one / "report.md").read_text()
    files = sorted(p.relative_to(one) for p in one.rglob("*.csv"))
    assert len(files) >= 15 and files == sorted(p.relative_to(out) for p in out.rglob("*.csv"))
    for f in files:
        assert (one / f).read_bytes() == (out / f).read_bytes(), f


def test_fork_is_refused_beside_another_thread():
    import threading

    ready, release = threading.Event(), threading.Event()
    other = threading.Thread(target=lambda: (ready.set(), release.wait(10)))
    other.start()
    try:
        ready.wait(10)
        assert not paper.fork_is_safe()
    finally:
        release.set()
        other.join()


def test_a_case_failing_in_a_worker_is_raised_with_its_traceback(tmp_path, monkeypatch):
    """A worker's failure stops the study with the case named and the worker's traceback."""
    def broken(case, *args, **kwargs):
        raise ValueError("deliberately broken case")

    monkeypatch.setattr(paper, "run_case", broken)
    monkeypatch.setattr(paper, "fork_is_safe", lambda: True)  # the worker must see the broken run_case
    with pytest.raises(RuntimeError, match=r"(?s)failed in a worker process.*deliberately broken case"):
        paper.run_cases(tmp_path, axial_steps=10, jobs=2)
