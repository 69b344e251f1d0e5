"""Linear solver backends: the fastest installed is the default, the choice falls back cleanly,
and every backend gives the same history to round-off."""

import numpy as np
import pytest
import scipy.sparse as sp

from rockfrac.case.schema import CaseError, parse_case
from rockfrac.output.csvout import read_csv
from rockfrac.run import run_case
from rockfrac.solve import linear
from rockfrac.studies import table1


def test_auto_prefers_pardiso_and_falls_back_without_it(monkeypatch):
    pytest.importorskip("pypardiso")
    assert isinstance(linear.make_solver("auto"), linear.Pardiso)
    monkeypatch.setattr(linear, "available", lambda: ["superlu"])
    assert isinstance(linear.make_solver("auto"), linear.SuperLU)


def test_a_missing_backend_is_a_clear_case_error(monkeypatch):
    monkeypatch.setattr(linear, "available", lambda: ["superlu"])
    d = table1.cse_case("rp", axial_steps=5)
    d["solver"] = {"linear": "pardiso"}
    with pytest.raises(CaseError, match=r"\[solver\].*linear = 'pardiso' is not installed here; available: \['superlu'\]"):
        parse_case(d, "c.toml")


@pytest.mark.parametrize("name", ["superlu", "pardiso"])
def test_repeated_factorizations_solve_fresh_matrices(name):
    if name == "pardiso":
        pytest.importorskip("pypardiso")
    solver = linear.make_solver(name)
    n = 2000
    rng = np.random.default_rng(0)
    for k in range(4):  # a new matrix each time: never a stale factorization
        a = sp.diags([rng.uniform(-1, 1, n - 1), 4.0 + k + rng.uniform(0, 1, n), rng.uniform(-1, 1, n - 1)],
                     [-1, 0, 1], format="csr")
        b = rng.standard_normal(n)
        x = solver.factorize(a).solve(b)
        assert np.abs(a @ x - b).max() < 1e-12


def test_backends_give_the_same_history(tmp_path):
    pytest.importorskip("pypardiso")
    out = {}
    for name in ("superlu", "pardiso"):
        d = table1.cse_case("rp", axial_steps=60, axial_displacement=1.5e-3, control="path")
        d["solver"] = {"linear": name}
        run_case(parse_case(d), tmp_path / name)
        out[name] = read_csv(tmp_path / name / "history.csv")
    np.testing.assert_allclose(out["pardiso"]["F_axial"], out["superlu"]["F_axial"], rtol=1e-9)
    np.testing.assert_allclose(out["pardiso"]["u_axial"], out["superlu"]["u_axial"], rtol=1e-9, atol=1e-15)
