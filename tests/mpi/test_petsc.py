"""PETSc backends on one process (issue 17's first step), run by ``make test`` in ``.venv-mpi``
(Debian's petsc4py; skipped in a venv without it): LU by MUMPS and GMRES + GAMG against SuperLU, and
a whole 3D cohesive run through PETSc against the serial one."""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp

pytest.importorskip("petsc4py")

from rockfrac.api import make_case, run  # noqa: E402
from rockfrac.case.build import build  # noqa: E402
from rockfrac.case.schema import parse_case  # noqa: E402
from rockfrac.mesh import rock_tests as rt  # noqa: E402
from rockfrac.solve import linear  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
TRIAXIAL = ROOT / "examples" / "rock_tests" / "triaxial"


def elastic_box_system(tmp_path, element: str, n: int):
    """The tangent (Dirichlet rows applied) and a right-hand side of an elastic box on rollers."""
    msh = rt.box(tmp_path / f"{element}.msh", (1.0, 1.0, 1.0), (n, n, n), element=element)
    case = make_case(mesh={"kind": "gmsh", "file": str(msh)}, bulk={"E": 2e10, "nu": 0.25},
                     stages=[{"name": "p", "displacement": {"left": {"x": 0.0}, "front": {"y": 0.0},
                                                           "bottom": {"z": 0.0}}, "pressure": {"top": 1e6}}])
    built = build(case)
    model = built.model
    model.set_dirichlet(built.stages[0].dirichlet)
    u = np.zeros(model.n_dofs)
    a = model.assemble(u, u, np.zeros(model.n_dofs)).matrix
    a = model.apply_dirichlet(sp.csr_matrix(a))
    b = np.random.default_rng(1).standard_normal(model.n_dofs)
    b[model.dirichlet] = 0.0
    return built, a, b


@pytest.mark.parametrize("element", ["hex8", "tet4"])
def test_petsc_lu_and_gamg_equal_superlu_on_a_3d_elastic_tangent(tmp_path, element):
    built, a, b = elastic_box_system(tmp_path, element, 6)
    ref = linear.SuperLU().solve(a, b)
    x = linear.make_solver("petsc").solve(a, b)
    assert np.abs(x - ref).max() <= 1e-10 * np.abs(ref).max()
    for name, most in (("petsc-gamg", 100), ("petsc-hypre", 200)):
        amg = linear.make_solver(name, built.mesh.nodes)
        factor = amg.factorize(a)
        x = factor.solve(b)
        assert np.linalg.norm(a @ x - b) <= 1e-10 * np.linalg.norm(b)
        assert np.abs(x - ref).max() <= 1e-7 * np.abs(ref).max()
        assert 0 < factor.iterations < most  # the AMG works: a few dozen iterations, not hundreds


@pytest.mark.parametrize("name", ["petsc", "petsc-gamg"])
def test_a_dropped_factor_destroys_its_ksp_and_a_held_one_goes_at_the_next(tmp_path, name):
    """Newton drops each factor before it assembles the next tangent: dropping it destroys the KSP
    (its factors or AMG hierarchy and Krylov vectors), which petsc4py would keep. A factor still held
    (a failed iteration's frame) is destroyed when the solver makes the next one: one KSP alive."""
    built, a, b = elastic_box_system(tmp_path, "hex8", 3)
    solver = linear.make_solver(name, built.mesh.nodes)
    factor = solver.factorize(a)
    ksp = factor._ksp
    x = factor.solve(b)
    assert np.linalg.norm(a @ x - b) <= 1e-9 * np.linalg.norm(b)
    assert ksp.handle != 0
    del factor
    assert ksp.handle == 0  # destroyed with the factor
    held = solver.factorize(a)
    ksp = held._ksp
    again = solver.factorize(a)
    assert ksp.handle == 0 and held._ksp is None  # the held one was released for the next
    assert np.abs(again.solve(b) - x).max() <= 1e-9 * np.abs(x).max()


@pytest.mark.parametrize("name", ["petsc", "petsc-gamg", "petsc-hypre"])
def test_a_singular_system_is_a_solver_failure(name):
    """A zero row with a nonzero right-hand side has no solution: SolverFailed (Newton then cuts back)."""
    d = np.ones(400)
    d[123] = 0.0
    a = sp.diags(d).tocsr() + sp.diags(np.full(399, 1e-3), 1).tocsr()
    a = a.tocsr()
    a.data[a.indptr[123]:a.indptr[124]] = 0.0  # row 123 all zero
    with pytest.raises(linear.SolverFailed):
        linear.make_solver(name).solve(a, np.ones(400))


def test_a_3d_cohesive_run_through_petsc_gives_the_serial_history(tmp_path):
    """The jointed triaxial cylinder (3D EP joint, slipping): [solver] linear = 'petsc' (MUMPS inside
    PETSc, one process) against the serial direct solver ('auto': PARDISO where installed, as in
    .venv-mpi, else SuperLU), every history column to 1e-9."""
    d = tomllib.loads((TRIAXIAL / "joint.toml").read_text())
    d["mesh"]["file"] = str(TRIAXIAL / d["mesh"]["file"])
    d["stages"][1]["steps"] = 20
    runs = {}
    for name in ("auto", "petsc"):
        d["solver"] = {"linear": name}
        runs[name] = run(parse_case(d, "joint.toml"), tmp_path / name).history
    a, b = runs["auto"], runs["petsc"]
    assert len(a["step"]) == len(b["step"]) and max(a["n_plastic"]) > 0
    for key in ("R_bottom_z", "u_top_z", "D_dissipated", "W_external"):
        scale = np.abs(a[key]).max()
        np.testing.assert_allclose(b[key], a[key], rtol=1e-9, atol=1e-9 * scale)
    assert list(a["newton_iterations"]) == list(b["newton_iterations"])


def built_dofs(out: Path) -> int:
    """The unknowns of the run written to ``out`` (its case.toml rebuilt)."""
    from rockfrac.case.schema import load_case

    return build(load_case(out / "case.toml")).model.n_dofs


def test_a_path_following_rp_run_through_petsc_gives_the_serial_history(tmp_path):
    """The paper's RP case (8 x 8 quads a block) under path control: bordered solves of saddle-point
    tangents with multiplier dofs, 'petsc' against SuperLU, the history to 1e-9."""
    from rockfrac.studies import table1

    runs = {}
    for name in ("superlu", "petsc"):
        d = table1.cse_case("rp", axial_steps=60, control="path", axial_displacement=1e-3)
        d["mesh"].update(nx=8, ny=8)  # 330 unknowns: above the dense path, so PETSc factorizes
        d["solver"] = {"linear": name}
        d["output"] = {"picture": False}
        runs[name] = run(parse_case(d, "rp.toml"), tmp_path / name).history
    a, b = runs["superlu"], runs["petsc"]
    assert len(a["step"]) == len(b["step"]) and max(a["n_plastic"]) > 0 and "path" in set(a["control"])
    assert built_dofs(tmp_path / "petsc") > linear.DENSE_UP_TO
    for key in ("F_axial", "u_axial", "jump_p_norm"):
        scale = np.nanmax(np.abs(a[key]))
        np.testing.assert_allclose(b[key], a[key], rtol=1e-9, atol=1e-9 * scale)
    # the same Newton path; a step may end one iteration apart where the round-off of the two
    # factorizations meets the convergence test
    assert np.abs(np.asarray(a["newton_iterations"]) - np.asarray(b["newton_iterations"])).max() <= 1


def test_rp_surfaces_on_every_edge_through_petsc_give_superlus_history(tmp_path, monkeypatch):
    """RP surfaces on every edge of the 4 x 6 specimen, held shut: a saddle point whose multiplier rows
    have zero diagonals, so MUMPS pivots off the diagonal beyond its analysis's workspace. With
    its default room (ICNTL(14) = 20 %) it stopped at the first step (INFOG(1) = -9, a "singular
    tangent"). Started with the saddle points' room (rockfrac.solve.petsc.MUMPS_SADDLE_WORKSPACE) it
    gives SuperLU's loads at once; started with MUMPS's default, it runs out, factorizes again with
    twice the room until it does not, says so in run.log, and gives the same loads."""
    import sys

    sys.path.insert(0, str(ROOT / "tests"))
    from conftest import EVERY_EDGE

    from rockfrac.solve import petsc
    from rockfrac.studies import table1

    runs, logs = {}, {}
    for name, start in (("superlu", None), ("petsc", None), ("petsc", 20)):
        if start is not None:
            monkeypatch.setattr(petsc, "MUMPS_SADDLE_WORKSPACE", start)
        label = f"{name}_{start}"
        d = dict(EVERY_EDGE, cohesive=dict(table1.CSE_LAW, form="rp", where="all"), solver={"linear": name},
                 output={"picture": False, "vtk": False, "points": False})
        result = run(parse_case(d, "every.toml"), tmp_path / label)
        assert result.summary.result.completed, result.summary.result.message
        runs[label], logs[label] = result.history, (tmp_path / label / "run.log").read_text()
    assert built_dofs(tmp_path / "petsc_None") > linear.DENSE_UP_TO
    a = runs["superlu_None"]["F_axial"]
    for label in ("petsc_None", "petsc_20"):
        np.testing.assert_allclose(runs[label]["F_axial"], a, rtol=1e-9, atol=1e-9 * np.abs(a).max())
    assert "ran out of workspace" not in logs["petsc_None"]
    grown = [line for line in logs["petsc_20"].splitlines() if "ran out of workspace" in line]
    assert grown and "ICNTL(14) = 20 %" in grown[0]  # from MUMPS's default, then doubled: once a run
    assert len(grown) == len(set(grown))  # the room that worked is kept for the next factorizations


def test_rp_joints_through_petsc_krylov_take_the_schur_field_split(tmp_path):
    """RP joints between the slabs of a 3D stack (saddle points), pressed, then dragged until a joint
    slides: petsc-gamg and petsc-hypre (GMRES with PETSc's Schur field split: the AMG on the
    displacements, MUMPS on the multipliers' selfp block) give SuperLU's history, step by step."""
    box = rt.box(tmp_path / "b.msh", (1.0, 1.0, 1.0), (2, 2, 4), element="tet4", layers=2)
    law = {"GfI": 50.0, "GfII": 500.0, "chi_p": 1e6, "chi_r": 0.0, "c_p": 2e6, "c_r": 0.0, "phi_p": 0.6,
           "phi_r": 0.5, "psi_p": 0.1, "alpha_chi": 5.0, "alpha_c": 5.0, "alpha_phi": 5.0, "alpha_psi": 5.0}
    held = {"bottom": {"x": 0.0, "y": 0.0, "z": 0.0}}
    runs = {}
    for name in ("superlu", "petsc-gamg", "petsc-hypre"):
        case = make_case(mesh={"kind": "gmsh", "file": str(box)}, bulk={"E": 2e10, "nu": 0.25},
                         cohesive={"where": "boundaries", "form": "rp", "augmentation": 1e12, **law},
                         stages=[{"name": "press", "displacement": held, "pressure": {"top": 1e6}},
                                 {"name": "drag", "steps": 6, "pressure": {"top": 1e6},
                                  "displacement": dict(held, top={"x": 1.75e-4, "y": 0.0})}],
                         solver={"linear": name}, output={"picture": False})
        r = run(case, tmp_path / name)
        assert r.completed, r.message
        runs[name] = r.history
    ref = runs["superlu"]
    assert ref["n_plastic"][-1] > 0
    for name in ("petsc-gamg", "petsc-hypre"):
        # the same Newton iterations, but for one where a step ends at round-off (an elastic drag
        # step whose first correction lands within the tolerance by SuperLU, just above it by GMRES)
        off = np.abs(runs[name]["newton_iterations"] - ref["newton_iterations"])
        assert off.max() <= 1 and np.count_nonzero(off) <= 1, (name, runs[name]["newton_iterations"])
        for q in ("R_top_x", "u_top_z"):
            np.testing.assert_allclose(runs[name][q], ref[q], rtol=0, atol=1e-9 * np.abs(ref[q]).max())
