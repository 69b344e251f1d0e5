"""Shared fixtures: the paper's CSE cases as dictionaries, and a runner returning the CSVs."""

import copy
import math

import pytest

from rockfrac.case.schema import parse_case
from rockfrac.output.csvout import read_csv
from rockfrac.runner import run_case
from rockfrac.studies import table1

TABLE1 = {
    "GfI": 1e4, "GfII": 1e4, "chi_p": 15680.0, "chi_r": 0.0, "c_p": 9053.0, "c_r": 0.0,
    "phi_p": 0.5236, "phi_r": 0.0, "psi_p": 0.087, "alpha_chi": 2e3, "alpha_c": 2e3,
    "alpha_phi": 9e2, "alpha_psi": 9e2,
}
THETA = table1.CRACK_ANGLE  # the EDE's bifurcation band (paper Sect. 7)
E, NU, P, W, H = 1.5e7, 0.3, 2e4, 0.04, 0.08


def paper_case(form: str = "rp", k: float | None = None, **loading) -> dict:
    """The paper's CSE specimen case (Table 1 law) as a dictionary."""
    coh = dict(TABLE1, form=form)
    if form == "ep":
        coh.update(kn=k, kt=k)
    load = {"confinement": P, "confinement_steps": 1, "axial_displacement": 1.5e-3, "axial_steps": 150}
    load.update(loading)
    return {"mesh": {"crack_angle": THETA}, "bulk": {"E": E, "nu": NU}, "cohesive": coh, "loading": load}


def with_law(case: dict, **law) -> dict:
    out = copy.deepcopy(case)
    out["cohesive"].update(law)
    return out


@pytest.fixture
def run(tmp_path):
    """run(case_dict, name) -> (history, points, summary)."""

    def _run(case: dict, name: str = "case"):
        out = tmp_path / name
        summary = run_case(parse_case(case, name), out)
        pts = read_csv(out / "points.csv") if (out / "points.csv").exists() else None
        return read_csv(out / "history.csv"), pts, summary

    return _run
