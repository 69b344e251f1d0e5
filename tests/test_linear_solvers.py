"""Linear solver backends: the fastest installed is the default, the choice falls back cleanly,
PARDISO analyses a pattern once, and every backend gives the same solutions and history to round-off."""

import sys

import numpy as np
import pytest
import scipy.sparse as sp

from rockfrac.case.build import build
from rockfrac.case.schema import CaseError, parse_case
from rockfrac.output.csvout import read_csv
from rockfrac.runner import run_case
from rockfrac.solve import linear
from rockfrac.solve.newton import Loads, NewtonOptions, newton_step
from rockfrac.solve.stepping import SteppingOptions, run_stages
from rockfrac.studies import table1

MODULES = {"pardiso": "pypardiso", "mumps": "mumps", "gmres-amg": "pyamg"}  # what each backend imports
DIRECT = [n for n in ("pardiso", "mumps") if n in linear.available()]


class _Enough(Exception):
    pass


def tangents(d: dict, count: int) -> list[sp.csr_matrix]:
    """The first ``count`` tangents (Dirichlet rows applied) of a run of case ``d``."""
    built = build(parse_case(d, "t.toml"))
    mats = []

    class Recorder(linear.SuperLU):
        name = "recorder"

        def factorize(self, a):
            mats.append(a.copy())
            if len(mats) >= count:
                raise _Enough
            return linear.SuperLU().factorize(a)

    with pytest.raises(_Enough):
        run_stages(built.model, built.stages, Recorder(), NewtonOptions(), SteppingOptions(), lambda info: None)
    return mats


def rp_case(n: int = 8) -> dict:
    d = table1.cse_case("rp", axial_steps=60, axial_displacement=1.5e-3, control="path")
    d["mesh"].update(nx=n, ny=n)
    return d


def dp_case(n: int = 8) -> dict:
    return {"mesh": {"kind": "specimen", "crack": False, "nx": n, "ny": n},
            "bulk": {"model": "drucker_prager", "E": 1.5e7, "nu": 0.3, "beta": 0.480385, "b": 0.321597,
                     "kappa0": 7532.54, "H": 43802.9},
            "loading": {"confinement": 2e4, "confinement_steps": 1, "axial_displacement": 2e-3, "axial_steps": 5}}


@pytest.fixture(scope="module")
def systems():
    """Real non-symmetric tangents of the paper's specimen: RP CSE still rigid (saddle point: zero
    diagonals on multiplier rows), RP CSE yielding, and a plastic non-associative Drucker-Prager block."""
    rp = tangents(rp_case(16), 41)
    dp = tangents(dp_case(), 5)
    out = {"rp rigid": rp[20], "rp plastic": rp[40], "dp plastic": dp[4], "rp sequence": rp[30:41]}
    for key in ("rp rigid", "rp plastic", "dp plastic"):
        a = out[key]
        assert abs(a - a.T).max() > 1e-3 * abs(a).max()  # really non-symmetric
    assert (out["rp rigid"].diagonal() == 0).sum() > 0
    return out


def block(monkeypatch, *names):
    """Make the backends ``names`` fail to import, as on a machine without their packages."""
    for name in names:
        monkeypatch.setitem(sys.modules, MODULES[name], None)


def direct_name(solver) -> str:
    """The backend's name; a checked one's (PARDISO under 'auto') is that of the backend it checks."""
    return solver.first.name if isinstance(solver, linear.Checked) else solver.name


def test_auto_takes_the_first_installed_in_preference_order(monkeypatch):
    order = [n for n in linear.PREFERENCE if n in linear.available()]
    assert order[-1] == "superlu" and "gmres-amg" not in linear.PREFERENCE
    assert direct_name(linear.make_solver("auto")) == order[0]
    for k, name in enumerate(order[:-1]):  # uninstall the preferred ones one by one
        block(monkeypatch, name)
        assert name not in linear.available()
        assert direct_name(linear.make_solver("auto")) == order[k + 1]


def test_asking_for_a_missing_backend_is_a_clear_error(monkeypatch):
    block(monkeypatch, "pardiso", "gmres-amg")
    with pytest.raises(ValueError, match=r"linear solver 'pardiso' is not installed here .*available: \[.*'superlu'"):
        linear.make_solver("pardiso")
    with pytest.raises(ValueError, match=r"unknown linear solver 'umfpack'; known: \["):
        linear.make_solver("umfpack")
    d = table1.cse_case("rp", axial_steps=5)
    d["solver"] = {"linear": "gmres-amg"}
    with pytest.raises(CaseError, match=r"\[solver\].*linear = 'gmres-amg' is not installed here; available: \["):
        parse_case(d, "c.toml")


@pytest.mark.parametrize("name", ["superlu", *DIRECT])
def test_repeated_factorizations_solve_fresh_matrices(name):
    solver = linear.make_solver(name)
    n = 2000
    rng = np.random.default_rng(0)
    for k in range(4):  # a new matrix each time: never a stale factorization
        a = sp.diags([rng.uniform(-1, 1, n - 1), 4.0 + k + rng.uniform(0, 1, n), rng.uniform(-1, 1, n - 1)],
                     [-1, 0, 1], format="csr")
        b = rng.standard_normal(n)
        x = solver.factorize(a).solve(b)
        assert np.abs(a @ x - b).max() < 1e-12


@pytest.mark.parametrize("name", DIRECT)
@pytest.mark.parametrize("key", ["rp rigid", "rp plastic", "dp plastic"])
def test_direct_backends_equal_superlu_on_real_tangents(systems, name, key):
    a = systems[key]
    b = np.random.default_rng(1).standard_normal(a.shape[0])
    ref = linear.SuperLU().solve(a, b)
    x = linear.make_solver(name).solve(a, b)
    assert np.abs(x - ref).max() <= 1e-9 * np.abs(ref).max()
    backward = np.abs(a @ x - b).max() / (abs(a).sum(axis=1).max() * np.abs(x).max() + np.abs(b).max())
    assert backward < 1e-14


def test_pardiso_analyses_a_pattern_once_and_equals_a_fresh_factorization(systems):
    pypardiso = pytest.importorskip("pypardiso")
    solver = linear.Pardiso()
    rng = np.random.default_rng(2)
    for a in systems["rp sequence"]:  # one run's tangents: same pattern, changing values
        b = rng.standard_normal(a.shape[0])
        x = solver.factorize(a).solve(b)
        fresh = pypardiso.PyPardisoSolver(mtype=11)  # analysis + factorization (phase 12) from scratch
        fresh.factorize(a)
        x_fresh = fresh.solve(a, b)
        fresh.free_memory(everything=True)
        assert np.abs(x - x_fresh).max() <= 1e-10 * np.abs(x_fresh).max()
    assert solver.analyses == 1 and solver.generation == len(systems["rp sequence"])
    # another pattern (another problem, then the same size with one entry more) is analysed afresh
    for a in (systems["dp plastic"], systems["rp plastic"] + sp.eye(systems["rp plastic"].shape[0], k=7) * 1e-3):
        a = sp.csr_matrix(a)
        b = rng.standard_normal(a.shape[0])
        x = solver.factorize(a).solve(b)
        assert np.abs(x - linear.SuperLU().solve(a, b)).max() <= 1e-9 * np.abs(x).max()
    assert solver.analyses == 3
    solver.begin_step()  # a load step starts: analysed afresh, on its first matrix
    solver.factorize(systems["rp plastic"])
    solver.factorize(systems["rp plastic"])
    assert solver.analyses == 4
    old = solver.factorize(systems["rp plastic"])
    solver.factorize(systems["rp plastic"])
    with pytest.raises(linear.SolverFailed, match="replaced"):  # its factors are gone
        old.solve(np.ones(systems["rp plastic"].shape[0]))


def test_pardiso_without_matching_keeps_its_analysis_from_step_to_step_bit_for_bit(systems):
    """Without MKL's matching the analysis reads the pattern only: kept across load steps, its factors
    solve every tangent of a run bit for bit as a fresh analysis on that tangent does; with the
    matching each step is analysed afresh."""
    pytest.importorskip("pypardiso")
    n_u = int(np.flatnonzero(systems["rp rigid"].diagonal() == 0).min())  # the first multiplier row
    rng = np.random.default_rng(5)
    for kwargs in ({"matching": False}, {"matching": False, "multipliers_from": n_u}, {}):
        kept = linear.Pardiso(**kwargs)
        for a in systems["rp sequence"]:
            kept.begin_step()
            b = rng.standard_normal(a.shape[0])
            x = kept.factorize(a).solve(b)
            if kwargs:  # without the matching: as a fresh analysis, bit for bit
                assert np.array_equal(x, linear.Pardiso(**kwargs).factorize(a).solve(b))
        assert kept.analyses == (1 if kwargs else len(systems["rp sequence"]))


def test_krylov_amg_equals_superlu_on_the_drucker_prager_tangent(systems):
    pytest.importorskip("pyamg")
    a = systems["dp plastic"]
    b = np.random.default_rng(3).standard_normal(a.shape[0])
    x = linear.make_solver("gmres-amg").solve(a, b)
    assert np.linalg.norm(a @ x - b) <= 1e-10 * np.linalg.norm(b)
    ref = linear.SuperLU().solve(a, b)
    assert np.abs(x - ref).max() <= 1e-7 * np.abs(ref).max()


def test_krylov_amg_solves_the_rp_saddle_points_given_the_nodes(systems):
    """Given the mesh's nodes the backend knows which rows are multipliers (after the displacements)
    and preconditions block-triangularly (rockfrac.solve.saddle): the rigid and the yielding RP
    tangents of the paper's specimen solve to the direct answer."""
    pytest.importorskip("pyamg")
    nodes = build(parse_case(rp_case(16), "t.toml")).mesh.nodes
    for key in ("rp rigid", "rp plastic"):
        a = systems[key]
        assert a.shape[0] > nodes.size  # multipliers
        b = np.random.default_rng(4).standard_normal(a.shape[0])
        solver = linear.make_solver("gmres-amg", nodes)
        factor = solver.factorize(a)
        x = factor.solve(b)
        assert np.linalg.norm(a @ x - b) <= 1e-10 * np.linalg.norm(b)
        ref = linear.SuperLU().solve(a, b)
        assert np.abs(x - ref).max() <= 1e-7 * np.abs(ref).max()
        assert factor.iterations < 200


def test_krylov_amg_reports_failure_on_the_rp_tangents_and_newton_cuts_back(systems):
    pytest.importorskip("pyamg")
    for key in ("rp rigid", "rp plastic"):  # without the nodes: AMG on the whole saddle point fails
        a = systems[key]
        b = np.random.default_rng(4).standard_normal(a.shape[0])
        with pytest.raises(linear.SolverFailed, match="GMRES did not converge"):
            linear.make_solver("gmres-amg").solve(a, b)
    assert issubclass(linear.SolverFailed, RuntimeError)  # what newton_step turns into a failed step
    built = build(parse_case(rp_case(16), "t.toml"))
    model, stage = built.model, built.stages[0]
    loads = Loads(np.zeros(model.dirichlet.shape[0]), stage.dirichlet_end, np.zeros(model.n_dofs), stage.f_ext_end)
    res = newton_step(model, np.zeros(model.n_dofs), 0.0, 1.0, loads, linear.make_solver("gmres-amg"), NewtonOptions())
    assert not res.converged and "GMRES did not converge" in res.message


def test_direct_backends_give_the_same_history(tmp_path):
    out = {}
    for name in ("superlu", *DIRECT):
        d = table1.cse_case("rp", axial_steps=60, axial_displacement=1.5e-3, control="path")
        d["solver"] = {"linear": name}
        run_case(parse_case(d), tmp_path / name)
        out[name] = read_csv(tmp_path / name / "history.csv")
    for name in DIRECT:  # (a step's iteration count may differ by one where a residual sits at the tolerance)
        assert len(out[name]["step"]) == len(out["superlu"]["step"])
        np.testing.assert_allclose(out[name]["F_axial"], out["superlu"]["F_axial"], rtol=1e-9)
        np.testing.assert_allclose(out[name]["u_axial"], out["superlu"]["u_axial"], rtol=1e-9, atol=1e-15)


def test_krylov_amg_gives_the_same_history_on_a_plastic_block(tmp_path):
    pytest.importorskip("pyamg")
    out = {}
    for name in ("superlu", "gmres-amg"):
        d = dp_case(6)
        d["solver"] = {"linear": name}
        run_case(parse_case(d), tmp_path / name)
        out[name] = read_csv(tmp_path / name / "history.csv")
    assert out["superlu"]["bulk_plastic"][-1] > 0.5  # a plastic, non-symmetric tangent
    assert len(out["gmres-amg"]["step"]) == len(out["superlu"]["step"])
    np.testing.assert_allclose(out["gmres-amg"]["F_axial"], out["superlu"]["F_axial"], rtol=1e-8)


def test_pardiso_finds_mkl_in_the_environment_and_keeps_a_users_path(monkeypatch, tmp_path):
    """The MKL runtime is taken from the environment's own library folder (no search through the whole
    environment per solver); a path the user set is left alone."""
    pytest.importorskip("pypardiso")
    monkeypatch.delenv("PYPARDISO_MKL_RT", raising=False)
    linear._find_mkl_runtime()
    path = linear.os.environ["PYPARDISO_MKL_RT"]
    assert "mkl_rt" in linear.os.path.basename(path) and linear.os.path.isfile(path)
    solver = linear.Pardiso()
    solver.dense_up_to = 0  # this small system through PARDISO itself
    a = sp.diags([np.full(9, -1.0), np.full(10, 4.0), np.full(9, -1.0)], [-1, 0, 1], format="csr")
    x = solver.factorize(a).solve(np.ones(10))
    assert np.abs(a @ x - 1.0).max() < 1e-13
    assert solver._solver.libmkl._name == path
    mine = str(tmp_path / "libmkl_rt.so.custom")
    monkeypatch.setenv("PYPARDISO_MKL_RT", mine)
    linear._find_mkl_runtime()
    assert linear.os.environ["PYPARDISO_MKL_RT"] == mine


needs_pardiso = pytest.mark.skipif("pardiso" not in linear.available(), reason="pypardiso not installed")


def elastic_tangent(n: int = 40) -> sp.csr_matrix:
    """The constrained elastic tangent of an n x n block (symmetric up to assembly round-off)."""
    return tangents({"mesh": {"kind": "specimen", "crack": False, "nx": n, "ny": n}, "bulk": {"E": 1.5e7, "nu": 0.3},
                     "loading": {"confinement": 2e4, "confinement_steps": 1, "axial_displacement": 1e-3,
                                 "axial_steps": 2}}, 1)[0]


@needs_pardiso
def test_pardiso_symmetric_mode_only_for_symmetric_matrices(systems):
    a = elastic_tangent()  # 3362 rows
    b = np.random.default_rng(2).standard_normal(a.shape[0])
    ref = linear.SuperLU().solve(a, b)
    p = linear.Pardiso()
    p.symmetric_from = 100
    x = p.factorize(a).solve(b)
    assert p.mtype == -2 and p.analyses == 1
    assert np.abs(x - ref).max() <= 1e-10 * np.abs(ref).max()
    assert np.abs(a @ x - b).max() <= 1e-10 * np.abs(b).max()
    # the unsymmetric answer to round-off
    q = linear.Pardiso()
    q.symmetric = "unsymmetric"
    y = q.factorize(a).solve(b)
    assert q.mtype == 11 and np.abs(x - y).max() <= 1e-10 * np.abs(y).max()
    # a nonassociative Drucker-Prager tangent and the RP saddle points keep the unsymmetric type
    for key in ("dp plastic", "rp plastic", "rp rigid"):
        t = systems[key]
        assert p.matrix_type(t) == 11, key
        bt = np.ones(t.shape[0])
        xt = p.factorize(t).solve(bt)
        assert p.mtype == 11 and np.abs(t @ xt - bt).max() <= 1e-8 * np.abs(bt).max(), key
    # a change of type analyses afresh; back to the symmetric one on the same pattern
    before = p.analyses
    p.factorize(a).solve(b)
    assert p.mtype == -2 and p.analyses == before + 1


@needs_pardiso
def test_pardiso_symmetry_check_tolerance_and_small_systems():
    a = elastic_tangent(12)
    p = linear.Pardiso()
    assert a.shape[0] < p.symmetric_from and p.matrix_type(a) == 11  # small: never checked
    p.symmetric_from = 10
    assert p.matrix_type(a) == -2
    skew = a.copy().tolil()
    i, j = 40, 41
    assert skew[i, j] != 0
    skew[i, j] = skew[i, j] + 1e-11 * abs(a).max()  # one entry off its mirror by 1e-11 max |A|
    assert p.matrix_type(skew.tocsr()) == 11
    unstructured = a.copy().tolil()
    unstructured[3, a.shape[0] - 1] = 1.0  # an entry without its mirror
    assert p.matrix_type(unstructured.tocsr()) == 11
    p.symmetric = "unsymmetric"
    assert p.matrix_type(a) == 11
    p.symmetric = "sometimes"
    with pytest.raises(ValueError, match="auto"):
        p.matrix_type(a)


@pytest.mark.parametrize("name", ["superlu", *DIRECT])
def test_tiny_systems_are_factorized_densely_with_the_sparse_answer(name):
    """At most DENSE_UP_TO rows: LAPACK's LU (no sparse set-up), the sparse backend's answer to
    round-off on the paper-size RP tangents (rigid: a saddle point, and yielding) and a 2-column
    right-hand side (path following's bordered solve); singular and non-finite matrices fail."""
    seq = tangents(rp_case(1), 45)  # the paper's RP specimen (20 rows): rigid, then yielding
    solver = linear.make_solver(name)
    sparse = linear.SOLVERS[name]()  # the backend itself (make_solver checks PARDISO's solves)
    sparse.dense_up_to = 0
    for t in (seq[1], seq[-1]):
        assert t.shape[0] <= linear.DENSE_UP_TO
        b = np.column_stack([np.ones(t.shape[0]), np.arange(t.shape[0], dtype=float)])
        factor = solver.factorize(t)
        assert type(factor).__name__ == "_DenseLU"
        x = factor.solve(b)
        other = sparse.factorize(t)
        assert type(other).__name__ != "_DenseLU"
        y = other.solve(b)
        assert x.shape == b.shape and np.abs(x - y).max() <= 1e-10 * np.abs(y).max()
        assert np.abs(t @ x - b).max() <= 1e-9 * np.abs(b).max()
    singular = sp.csr_matrix(np.array([[1.0, 2.0], [2.0, 4.0]]))
    with pytest.raises(linear.SolverFailed, match="singular"):
        solver.factorize(singular)
    with pytest.raises(linear.SolverFailed, match="non-finite"):
        solver.factorize(sp.csr_matrix(np.array([[1.0, np.nan], [0.0, 1.0]])))
    big = elastic_tangent(8)  # 162 rows: above the threshold
    assert big.shape[0] > linear.DENSE_UP_TO and type(solver.factorize(big)).__name__ != "_DenseLU"


def test_auto_in_3d_takes_amg_from_its_size_and_hands_over_to_the_direct_backend(systems):
    """'auto': a 3D model of AMG_FROM_3D dofs or more without nodal cracks' enrichment gets GMRES +
    AMG (six rigid-body modes), a smaller one, a 2D one or one with enrichment the direct backend; at the
    first failure of GMRES the direct backend solves, the same iteration and from then on."""
    pytest.importorskip("pyamg")
    direct = linear.make_solver("auto").name

    def plain(solver) -> str:  # the direct chain's name, whether or not it orders a saddle point
        return solver.name.replace(", saddle ordering", "")

    x3 = np.random.default_rng(0).uniform(size=(10, 3))
    big = linear.AMG_FROM_3D
    assert isinstance(linear.make_solver("auto", x3, big), linear.Handover)
    assert plain(linear.make_solver("auto", x3, big - 1)) == direct
    assert linear.make_solver("auto", x3, big, enrichment=True).name == direct
    assert plain(linear.make_solver("auto", x3[:, :2], 10 * big)) == direct
    # the rigid-body modes: a rigid motion has no strain, so K B = 0 on an unconstrained elastic body
    from rockfrac.elements.solid import ElasticSolid
    from rockfrac.fem.reference import HEX8
    from rockfrac.mesh import hex_specimen

    m = hex_specimen(1.0, 2.0, 1.5, 2, 3, 2)
    k = sp.csr_matrix(sp.block_diag([sp.csr_matrix(ke) for ke in ElasticSolid(m.nodes, m.cells, HEX8, 1e9, 0.3).ke]))
    gather = sp.csr_matrix((np.ones(24 * len(m.cells)), ((3 * m.cells[:, :, None] + np.arange(3)).ravel(),
                                                         np.arange(24 * len(m.cells)))),
                           shape=(3 * m.n_nodes, 24 * len(m.cells)))
    kg = gather @ k @ gather.T
    modes = linear.rigid_modes_3d(m.nodes)
    assert np.abs(kg @ modes).max() <= 1e-9 * abs(kg).max()
    assert np.linalg.matrix_rank(modes) == 6
    # handover on a saddle-point tangent GMRES cannot solve
    a = systems["rp rigid"]
    b = np.random.default_rng(4).standard_normal(a.shape[0])
    solver = linear.Handover(linear.make_solver("gmres-amg"), linear.SuperLU())
    x = solver.solve(a, b)
    assert "GMRES did not converge" in solver.failed
    assert np.linalg.norm(a @ x - b) <= 1e-10 * np.linalg.norm(b)
    assert solver.factorize(a).solve(b) == pytest.approx(x, rel=1e-12, abs=1e-12 * np.abs(x).max())
