"""Nonlinear elimination (rockfrac.solve.elimination): a stalled Newton iteration solves the few
unknowns that carry its residual alone, every other unknown held."""

import numpy as np
import pytest

from rockfrac.elements.base import ElementGroup, Evaluation
from rockfrac.model import Model
from rockfrac.solve.elimination import MOST_UNKNOWNS, REDUCTION, eliminate, stalled, stalled_unknowns
from rockfrac.solve.linear import make_solver
from rockfrac.solve.newton import Loads, NewtonOptions, newton_step

A = 0.3  # the kinked unknown's root [m]


class Kinked(ElementGroup):
    """One element on dofs 0..n-1: internal forces (sign(x - A) sqrt|x - A| + 1e-3 (x - y_1), K y - b + ...)
    [N]. Newton's correction of x alone maps x - A to -(x - A): from anywhere plain Newton's iterates
    go round a 2-cycle of (nearly) equal residuals, while the other unknowns, linear and weakly
    coupled, converge at once (a halving of the correction would land on the kink)."""

    def __init__(self, n: int = 6):
        self.dofs = np.arange(n)[None, :]
        rng = np.random.default_rng(0)
        m = rng.standard_normal((n - 1, n - 1))
        self.k = m @ m.T + n * np.eye(n - 1)  # symmetric positive definite
        self.b = rng.standard_normal(n - 1)

    def evaluate(self, u, u_n):
        x, y = u[0], u[1:]
        s = x - A
        fe = np.empty((1, u.size))
        ke = np.zeros((1, u.size, u.size))
        fe[0, 0] = np.sign(s) * np.sqrt(abs(s)) + 1e-3 * (x - y[0])
        fe[0, 1:] = self.k @ y - self.b
        fe[0, 1] += 1e-3 * (y[0] - x)
        ke[0, 0, 0] = 0.5 / np.sqrt(max(abs(s), 1e-300)) + 1e-3
        ke[0, 0, 1] = ke[0, 1, 0] = -1e-3
        ke[0, 1:, 1:] = self.k
        ke[0, 1, 1] += 1e-3
        return Evaluation(fe, ke)


def model_of(n: int = 6) -> Model:
    return Model(n // 2, [Kinked(n)], np.zeros(0, dtype=np.int64), dim=2)


def solve(eliminate_: bool, n: int = 6):
    """Plain Newton (no line search: its halvings would land on the kink) from x = A + 0.04."""
    model = model_of(n)
    zero = np.zeros(n)
    loads = Loads(np.zeros(0), np.zeros(0), zero, zero)
    u0 = np.zeros(n)
    u0[0] = A + 0.04
    options = NewtonOptions(max_iterations=25, line_search=0, eliminate=eliminate_)
    return newton_step(model, u0, 0.0, 1.0, loads, make_solver("superlu"), options)


def test_the_stalled_unknowns_are_the_fewest_that_carry_the_residual():
    free = np.arange(100)
    r = np.full(100, 1e-6)
    r[[7, 42, 3]] = [3.0, -2.0, 2.0]
    assert stalled_unknowns(r, free).tolist() == [3, 7, 42]  # two of them carry sqrt(13 / 17) = 0.87 < 0.9
    r[[7, 42, 3]] = [3.0, -2.0, 0.5]
    assert stalled_unknowns(r, free).tolist() == [7, 42]  # sqrt(13 / 13.25) = 0.99
    assert stalled_unknowns(r, free[free != 7]).tolist() == [42]  # only free dofs count: sqrt(4 / 4.25)
    spread = np.ones(100)  # no few unknowns carry it
    assert stalled_unknowns(spread, free) is None
    assert stalled_unknowns(np.zeros(100), free) is None
    assert MOST_UNKNOWNS < 100


def test_a_stall_is_a_residual_above_half_the_least_of_the_five_before():
    assert not stalled([1.0, 0.9, 1.1, 0.95, 1.0, 0.98])  # too early: the first iterates may wander
    assert stalled([1.0, 0.9, 1.1, 0.95, 1.0, 0.98, 0.6])
    assert not stalled([1.0, 0.9, 1.1, 0.95, 1.0, 0.98, 0.4])
    assert not stalled([1.0, 1e-1, 1e-2, 1e-3, 1e-4, 1e-5, 1e-6])  # linear convergence, rate 0.1
    # the grains' step 1211 (benchmarks/README.md, "Why its steps fail"): a 3-cycle, not converging
    assert stalled([0.22, 1.6e-3, 1.5e-4, 6.3e-6, 2.4e-6, 3.2e-6, 2.0e-6, 8.0e-6, 2.9e-6])


def test_elimination_solves_the_kinked_unknown_and_holds_the_others():
    model = model_of()
    u = np.zeros(6)
    u[0] = A + 0.04
    k = Kinked()
    u[1:] = np.linalg.solve(k.k, k.b)  # the linear unknowns (nearly) at their solution
    zero = np.zeros(6)
    asm = model.assemble(u, u, zero)
    assert stalled_unknowns(asm.residual, model.free).tolist() == [0]
    got = eliminate(model, u, u, zero, asm)
    assert got is not None and got.unknowns.tolist() == [0]
    assert got.after <= REDUCTION * got.before
    assert np.array_equal(got.u[1:], u[1:])  # held
    assert got.u[0] == pytest.approx(A, abs=1e-6)  # sqrt|x - A| <= 1e-3 of 0.2
    np.testing.assert_array_equal(got.assembled.residual, model.assemble(got.u, u, zero).residual)


def test_a_two_cycle_of_plain_newton_is_broken_by_the_elimination():
    plain = solve(eliminate_=False)
    assert not plain.converged and "cycle between two states" in plain.message
    assert plain.eliminated == []
    res = solve(eliminate_=True)
    assert res.converged and res.eliminated  # a local solve, then Newton's own iterations
    assert res.iterations <= 10
    r = model_of().assemble(res.u, res.u, np.zeros(6)).residual
    assert np.abs(r).max() <= 1e-8  # the whole system's equilibrium
    assert res.u[0] == pytest.approx(A, abs=1e-6)  # the root, moved by the weak coupling
    from rockfrac.solve.stepping import _log_iterations

    lines: list[str] = []
    _log_iterations(lines.append, "s", 1, res)  # run.log says which iterates came from a local solve
    local = [ln for ln in lines if "local solve" in ln]
    assert res.eliminated_unknowns == [1] * len(res.eliminated)
    assert [int(ln.split(" it ")[1].split(":")[0]) for ln in local] == [e + 1 for e in res.eliminated]
    assert local[0].endswith("after a local solve of 1 unknown (elimination)")


def test_the_option_reaches_newton_and_a_run_that_never_stalls_is_unchanged(run):
    """[solver] elimination = true: Newton's option; the paper's EP case, whose steps converge in a few
    iterations, never stalls, so its history is bit for bit that without it."""
    from conftest import paper_case

    from rockfrac.case.build import build
    from rockfrac.case.schema import parse_case
    from rockfrac.runner import engine_options

    case = paper_case("ep", 1e12, axial_steps=30, axial_displacement=0.6e-3)
    on = dict(case, solver=dict(case.get("solver", {}), elimination=True))
    assert engine_options(build(parse_case(on, "on")))[0].eliminate
    assert not engine_options(build(parse_case(case, "off")))[0].eliminate
    h_off, _, _ = run(case, "off")
    h_on, _, _ = run(on, "on")
    assert h_off["newton_iterations"].max() >= 3  # the surface yields in the run
    assert h_on.keys() == h_off.keys()
    for key in h_off:
        np.testing.assert_array_equal(h_on[key], h_off[key])


def test_a_case_without_the_key_resolves_to_the_text_it_had_before_the_key():
    """A checkpoint's case digest is that of the resolved case's text: unset, the key is not in it, so
    the runs checkpointed before it existed still resume (the grains' bundles)."""
    from conftest import paper_case

    from rockfrac.case.schema import parse_case

    case = parse_case(paper_case("ep", 1e12), "off")
    assert "elimination" not in case.model_dump(mode="json", exclude_none=True)["solver"]
    on = paper_case("ep", 1e12)
    on["solver"] = {"elimination": True}
    assert parse_case(on, "on").model_dump(mode="json", exclude_none=True)["solver"]["elimination"] is True
