"""``rockfrac paper`` end to end on a small step count; the example files equal Table 1."""

from pathlib import Path

import numpy as np
import pytest

from rockfrac.case.schema import load_case, parse_case
from rockfrac.cli import main
from rockfrac.output.csvout import read_csv
from rockfrac.studies import table1

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize("name,key", [("cse_ep_k1e9", "EP CSE k=1e9"), ("cse_ep_k1e8", "EP CSE k=1e8"),
                                      ("cse_rp", "RP CSE")])
def test_example_case_files_are_the_study_cases(name, key):
    example = load_case(ROOT / "examples" / "paper" / f"{name}.toml")
    study = parse_case(table1.paper_cse_cases()[key])
    for section in ("mesh", "bulk", "cohesive"):
        assert getattr(example, section) == getattr(study, section), section
    assert example.loading.confinement == study.loading.confinement


def test_paper_command_writes_figures_csvs_and_report(tmp_path):
    out = tmp_path / "paper"
    assert main(["paper", "--out", str(out), "--steps", "80", "--quiet"]) == 0
    for stem in ("fig5_force_displacement", "fig7_cohesion", "fig8_friction", "fig9_dilation"):
        png = out / f"{stem}.png"
        assert png.stat().st_size > 20_000  # a real plot, not an empty canvas
        data = read_csv(out / f"{stem}.csv")
        assert set(data["case"]) == {"EP CSE k=1e9", "EP CSE k=1e8", "RP CSE"}
    fig5 = read_csv(out / "fig5_force_displacement.csv")
    for case in ("EP CSE k=1e9", "EP CSE k=1e8", "RP CSE"):
        f = fig5["F_axial"][fig5["case"] == case]
        assert f[-1] < 0.6 * f.max()  # deep into softening
    report = (out / "report.md").read_text()
    assert "Table 1" in report and "fig5_force_displacement.png" in report
    c = read_csv(out / "fig7_cohesion.csv")
    rp = c["case"] == "RP CSE"
    assert np.all(np.diff(c["c"][rp]) < 0)
