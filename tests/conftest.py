"""Shared fixtures: the paper's CSE cases as dictionaries, and a runner returning the CSVs."""

import copy
import math
import os
from pathlib import Path

import numpy as np
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


def pressed_then_pulled(nx: int, ny: int) -> dict:
    """An elastic block pressed (4 steps; its right side free to bulge), then its right side held
    from where it is and pulled (8 steps), a checkpoint every 5 steps: a resume inside the second
    stage, whose start values of the right side come from the end of the first."""
    return {"mesh": {"kind": "block", "element": "quad4", "width": 0.04, "height": 0.08, "nx": nx, "ny": ny},
            "materials": [{"region": "bulk", "model": "elastic", "E": 1.5e7, "nu": 0.3}],
            "stages": [{"name": "press", "steps": 4, "displacement": {"bottom": {"y": 0.0}, "bottom_left": {"x": 0.0},
                                                                     "top": {"y": -4e-4}}},
                       {"name": "pull", "steps": 8, "displacement": {"right": {"x": 2e-4}}}],
            "output": {"picture": False, "points": False, "checkpoint_every": 5}}


# an elastic 4 x 6 quad specimen, confined and compressed: cohesive surfaces on every edge of it are
# loops of 4 pairs round each interior node (tests/test_real_meshes.py, tests/test_nested_multipliers.py)
EVERY_EDGE = {"mesh": {"kind": "specimen", "crack": False, "nx": 4, "ny": 6}, "bulk": {"E": 1.5e7, "nu": 0.3},
              "loading": {"confinement": 2e4, "axial_displacement": 2e-4, "axial_steps": 4}}


def check_tied_every_edge(unsplit: Path, tied: Path, rtol: float, jump: float) -> None:
    """RP surfaces on every edge of EVERY_EDGE, held constrained (run folder ``tied``): the unsplit
    specimen's loads (run folder ``unsplit``) to rtol, no jump above ``jump`` [m], and at the junctions
    the physical tractions sigma . n (least circulation)."""
    a, b = read_csv(unsplit / "history.csv"), read_csv(tied / "history.csv")
    p = read_csv(tied / "points.csv")
    np.testing.assert_allclose(b["F_axial"], a["F_axial"], rtol=rtol)
    assert np.abs(p["jump_t"]).max() < jump and np.abs(p["jump_n"]).max() < jump
    assert set(p["state"]) == {"constrained"}
    last = p["step"] == p["step"].max()
    horizontal = last & (np.abs(p["angle"]) < 0.1)
    vertical = last & (np.abs(p["angle"]) > 1.0)
    np.testing.assert_allclose(p["T_n"][horizontal], -a["F_axial"][-1] / 0.04, rtol=rtol)
    np.testing.assert_allclose(p["T_n"][vertical], -2e4, rtol=rtol)
    assert np.abs(p["T_t"][last]).max() < 1e-6 * 2e4


def check_uniform_tractions_3d(points_csv: Path, sigma: np.ndarray, scale: float) -> np.ndarray:
    """RP surfaces of a 3D patch test held shut under the uniform stress ``sigma`` [Pa]: at the last step
    each point's T_n and shear magnitude are sigma . n's to 1e-9 of ``scale``, and no jump; returns the
    points' shear magnitudes [Pa]."""
    p = read_csv(points_csv)
    last = p["step"] == p["step"].max()
    n = np.stack([p["n_x"], p["n_y"], p["n_z"]], axis=1)[last]
    t = n @ sigma
    t_n = np.einsum("pi,pi->p", t, n)
    assert np.abs(p["T_n"][last] - t_n).max() <= 1e-9 * scale
    shear = np.linalg.norm(t - t_n[:, None] * n, axis=1)
    assert np.abs(np.hypot(p["T_t1"][last], p["T_t2"][last]) - shear).max() <= 1e-9 * scale
    assert np.abs(p["jump_n"]).max() < 1e-15 and np.abs(p["jump_t1"]).max() < 1e-15
    return shear


def check_cohesive_tangent(model, group, seed: int, step: float) -> np.ndarray:
    """The model's tangent against central differences of its internal forces (40 random columns, steps
    of ``step`` times the scale) at a random state of jumps of 3e-9 m (and RP multipliers of 2e4 Pa)
    where some of ``group``'s points are plastic and others not; returns that state."""
    import scipy.sparse as sp

    rng = np.random.default_rng(seed)
    u = np.zeros(model.n_dofs)
    u[:model.n_u] = 3e-9 * rng.standard_normal(model.n_u)
    lam = getattr(group, "lam_dofs", None)
    if lam is not None:
        u[lam] = 2e4 * rng.standard_normal(lam.shape)
    u_n = np.zeros(model.n_dofs)

    def forces(v: np.ndarray) -> tuple[np.ndarray, sp.csr_matrix]:
        model.begin_step()
        asm = model.assemble(v, u_n, np.zeros(model.n_dofs))
        return asm.f_int, sp.csr_matrix(asm.matrix)

    _, a = forces(u)
    plastic = int(np.count_nonzero(group.trial[:, group.mode] == 1.0))
    assert 0 < plastic < group.points.n
    for j in rng.choice(model.n_dofs, 40, replace=False):
        h = step * (3e-9 if j < model.n_u else 2e4)
        e = np.zeros(model.n_dofs)
        e[j] = h
        fd = (forces(u + e)[0] - forces(u - e)[0]) / (2 * h)
        col = a[:, j].toarray().ravel()
        assert np.linalg.norm(fd - col) <= 1e-6 * max(np.linalg.norm(col), 1e-30), j
    return u


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


# The test files that take longest, longest first (seconds a file on one worker, measured 2026-11-30):
# `make test` hands whole files to its 2 pytest-xdist workers in collection order
# (`--dist loadfile --no-loadscope-reorder`), so the long ones start first and the short ones fill
# in at the end (xdist's own reordering, by the number of tests in a file, sent the one-test 53 s
# file among the last). Files not listed follow in pytest's order. A stale list costs balance only.
LONGEST_FIRST = (
    "test_edge_points.py",  # 95 s (2026-12-01)
    "test_examples.py",  # 74 s
    "test_nodal_3d.py",  # 68
    "test_resume_and_vtk.py",  # 68
    "test_nodal_bands.py",  # 59
    "test_ede_3d.py",  # 54
    "test_band_meshes.py",  # 53
    "test_paper_study.py",  # 47
    "test_rock_tests.py",  # 45
    "test_solids_3d.py",  # 39
    "test_traction3d.py",  # 34
    "test_embedded_cracks.py",  # 31
    "test_path_controls.py",  # 29
    "test_viscous.py",  # 26
    "test_crack_tracking.py",  # 25
    "test_fast_paths.py",  # 23
    "test_interrupts.py",  # 20
)


def pytest_collection_modifyitems(session, config, items):
    """The tests of the LONGEST_FIRST files first, in that order (a stable sort: a file's own tests
    keep their order)."""
    rank = {name: k for k, name in enumerate(LONGEST_FIRST)}
    items.sort(key=lambda item: rank.get(item.path.name, len(rank)))


def pytest_sessionfinish(session, exitstatus):
    """With ROCKFRAC_RECORD_KERNELS set, a pytest-xdist worker writes the kernel signatures it used
    (rockfrac.precompile; a worker ends without running Python's exit handlers, other processes
    write theirs when they exit)."""
    folder = os.environ.get("ROCKFRAC_RECORD_KERNELS")
    if folder and os.environ.get("PYTEST_XDIST_WORKER"):
        from rockfrac.precompile import record

        record(Path(folder))
