"""Checked solves: a backend's solution is checked against its equations; an inaccurate one is
refined with its own factors, else solved again by another backend, which takes over for the rest of
the run at the third matrix where it is accurate (PARDISO's static pivoting on RP saddle points,
benchmarks/README.md "Fragmentation")."""

import warnings

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from test_linear_solvers import rp_case, tangents

from rockfrac.solve import linear
from rockfrac.solve.fallback import ACCURACY, HAND_OVER_AFTER, REFINE_STEPS, Checked, relative_residual

needs_pardiso = pytest.mark.skipif("pardiso" not in linear.available(), reason="PARDISO (pypardiso) not installed")


class Perturbed(linear.SuperLU):
    """Factors of A + delta max|A| I instead of A: what a static pivoting backend does to pivots it
    finds too small, here to every one. Counts its factorizations and steps."""

    name = "perturbed"
    dense_up_to = 0

    def __init__(self, delta: float):
        self.delta, self.factorizations, self.steps = delta, 0, 0

    def begin_step(self) -> None:
        self.steps += 1

    def _factorize(self, a):
        self.factorizations += 1
        return spla.splu((a + self.delta * abs(a).max() * sp.eye(a.shape[0])).tocsc())


class Counting(linear.SuperLU):
    name = "counting"
    dense_up_to = 0

    def __init__(self):
        self.factorizations, self.steps = 0, 0

    def begin_step(self) -> None:
        self.steps += 1

    def _factorize(self, a):
        self.factorizations += 1
        return super()._factorize(a)


@pytest.fixture(scope="module")
def saddle():
    """The paper's RP specimen on 16 x 16 quads, its CSE still rigid: a real saddle point (zero
    diagonals on its multiplier rows), 600-odd rows."""
    a = tangents(rp_case(16), 21)[20]
    assert a.shape[0] > linear.DENSE_UP_TO and (a.diagonal() == 0).any()
    return a


def test_relative_residual():
    a = sp.csr_matrix(np.array([[2.0, 0.0], [0.0, 4.0]]))
    b = np.array([2.0, 4.0])
    assert relative_residual(a, np.array([1.0, 1.0]), b) == 0.0
    assert relative_residual(a, np.array([1.0, 0.0]), b) == pytest.approx(4.0 / np.hypot(2.0, 4.0), rel=1e-15)
    assert relative_residual(a, np.array([0.5, 0.0]), np.zeros(2)) == 1.0  # b = 0: the residual itself
    assert relative_residual(a, np.array([np.nan, 1.0]), b) == np.inf
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no overflow warning, and inf rather than NaN
        assert relative_residual(a, np.array([1e300, -1e300]), b) == np.inf
        big = sp.csr_matrix(np.array([[1e300, 1e300], [0.0, 1.0]]))
        assert relative_residual(big, np.array([1e10, -1e10]), b) == np.inf  # inf - inf in A x
    two = np.column_stack([b, 2 * b])  # path following's two right-hand sides
    assert relative_residual(a, np.column_stack([[1.0, 1.0], [2.0, 2.0]]), two) == 0.0


class _Scaled:
    def __init__(self, lu, scale):
        self.lu, self.scale = lu, scale

    def solve(self, b):
        return self.scale * self.lu.solve(b)


class Blowup(linear.SuperLU):
    """A backend off by a factor: ``scale`` 1e305 makes A x overflow (as PARDISO's perturbed factors
    did on the disc's RP saddle points, residuals to 1e143 and beyond)."""

    name = "blowup"
    dense_up_to = 0

    def __init__(self, scale: float):
        self.scale = scale

    def _factorize(self, a):
        return _Scaled(spla.splu(a.tocsc()), self.scale)


def test_of_two_inaccurate_solves_the_better_stands_also_where_the_first_overflows(saddle):
    """First's solution overflows A x (its residual inf, not NaN): then's, inaccurate but finite and
    better, is the one returned; where then's is the worse, first's stands."""
    b = np.random.default_rng(3).standard_normal(saddle.shape[0])
    exact = spla.spsolve(saddle.tocsc(), b)
    # off by 2.5 and 3 (residuals 1.5 and 2): refinement with such factors does not contract
    for first, then, expected in ((Blowup(1e305), Blowup(2.5), 2.5 * exact), (Blowup(2.5), Blowup(3.0), 2.5 * exact)):
        solver = Checked(first, then)
        with warnings.catch_warnings():
            warnings.simplefilter("error", RuntimeWarning)
            x = solver.solve(saddle, b)
        assert np.allclose(x, expected, rtol=1e-9, atol=1e-12 * np.abs(exact).max())
        assert solver.off == 1 and not solver.handed_over


def test_an_inaccurate_solve_is_solved_again_and_the_accurate_backend_takes_over_at_the_third(saddle):
    rng = np.random.default_rng(0)
    first, then = Perturbed(1e-9), Counting()
    solver = Checked(first, then)
    solver.begin_step()
    assert first.steps == then.steps == 1  # both are told a step starts
    b = rng.standard_normal(saddle.shape[0])
    exact = spla.splu(saddle.tocsc()).solve(b)
    assert relative_residual(saddle, first.factorize(saddle).solve(b), b) > 1e3 * ACCURACY  # really off
    first.factorizations = 0
    for k in range(1, HAND_OVER_AFTER):  # then's factors of this matrix only; the first backend kept
        factor = solver.factorize(saddle)
        assert first.factorizations == k and then.factorizations == k - 1 and not solver.handed_over
        x = factor.solve(b)
        assert then.factorizations == k and relative_residual(saddle, x, b) < 1e-12
        assert np.abs(x - exact).max() <= 1e-10 * np.abs(exact).max()
        y = factor.solve(2 * b)  # the same factor's next solve: then's factors, not checked again
        assert then.factorizations == k and solver.solves == k and np.abs(y - 2 * x).max() <= 1e-12 * np.abs(x).max()
        assert not solver.handed_over and solver.retried == k
    assert "counting solved 2 of them again, accurately" in solver.notes()[1]
    x = solver.factorize(saddle).solve(b)  # the third: then takes over
    assert first.factorizations == HAND_OVER_AFTER == then.factorizations and relative_residual(saddle, x, b) < 1e-12
    assert "perturbed's solution of a" in solver.handed_over and "the 3rd such system" in solver.handed_over
    assert "counting solved from then on" in solver.handed_over
    solver.factorize(saddle).solve(b)  # from then on the first backend is not asked
    assert first.factorizations == HAND_OVER_AFTER and then.factorizations == HAND_OVER_AFTER + 1
    notes = solver.notes()
    assert len(notes) == 2 and "3 of 3 solves by perturbed left relative residuals above 1e-06" in notes[0]
    assert "solved from then on" in notes[1]


def test_a_slightly_inaccurate_solve_is_refined_with_the_first_backends_factors(saddle):
    """Factors of a slightly perturbed matrix (1e-13 max|A| on every pivot: the first solution is off by
    about 3e-3) converge under iterative refinement: the solution meets the accuracy without the
    other backend, which is never asked, and the first one keeps solving."""
    b = np.random.default_rng(4).standard_normal(saddle.shape[0])
    first, then = Perturbed(1e-13), Counting()
    plain = first.factorize(saddle).solve(b)
    assert relative_residual(saddle, plain, b) > 1e3 * ACCURACY
    solver = Checked(first, then)
    x = solver.factorize(saddle).solve(b)
    assert then.factorizations == 0 and not solver.handed_over
    assert relative_residual(saddle, x, b) <= ACCURACY
    exact = spla.splu(saddle.tocsc()).solve(b)
    assert np.abs(x - exact).max() <= 1e-5 * np.abs(exact).max()
    assert solver.off == 1 and solver.refined == 1 and 1 < solver.refine_steps <= REFINE_STEPS
    solver.factorize(saddle).solve(2 * b)  # and again: still the first backend's
    assert first.factorizations == 3 and then.factorizations == 0 and solver.refined == 2
    notes = solver.notes()
    assert "2 of 2 solves by perturbed" in notes[0] and "2 of them met it after iterative refinement" in notes[1]


def test_refinement_that_does_not_contract_is_abandoned(saddle):
    """Factors too far off (1e-9 max|A| on every pivot of the saddle point) do not contract under
    refinement: the first correction is rejected, and the other backend solves as before."""
    b = np.random.default_rng(5).standard_normal(saddle.shape[0])
    solver = Checked(Perturbed(1e-9), Counting())
    x = solver.factorize(saddle).solve(b)
    assert solver.refined == 0 and solver.refine_steps == 0 and solver.retried == 1
    assert relative_residual(saddle, x, b) < 1e-12


def test_an_accurate_solve_is_the_first_backends_own(saddle):
    b = np.random.default_rng(1).standard_normal(saddle.shape[0])
    first, then = Counting(), Counting()
    solver = Checked(first, then)
    x = solver.factorize(saddle).solve(b)
    assert first.factorizations == 1 and then.factorizations == 0 and not solver.handed_over and solver.notes() == []
    assert np.array_equal(x, first.factorize(saddle).solve(b))  # bit for bit what the first backend gives
    assert solver.solves == 1 and solver.off == 0 and 0 < solver.worst <= ACCURACY


def test_a_singular_system_keeps_the_first_backend_and_the_better_solution():
    """A mechanism (a zero row and column): no backend solves it, the other one raises; the first
    backend's solution is returned, and it keeps solving."""
    n = 300
    a = sp.diags([np.r_[np.ones(n - 1), 0.0] * 4.0, -np.ones(n - 1), -np.ones(n - 1)], [0, 1, -1], format="lil")
    a[n - 2, n - 1] = a[n - 1, n - 2] = 0.0
    a = a.tocsr()
    b = np.ones(n)
    first, then = Perturbed(1e-6), Counting()
    solver = Checked(first, then)
    x = solver.factorize(a).solve(b)  # SuperLU: "exactly singular"
    assert then.factorizations == 1 and not solver.handed_over and np.all(np.isfinite(x))
    assert np.array_equal(x, first.factorize(a).solve(b))
    solver.factorize(a).solve(b)
    assert first.factorizations == 3 and solver.off == 2
    assert "2 of 2 solves by perturbed" in solver.notes()[0]


def test_of_two_inaccurate_solutions_the_smaller_residual_is_returned(saddle):
    b = np.random.default_rng(2).standard_normal(saddle.shape[0])
    worse, better = Perturbed(1e-6), Perturbed(1e-9)
    x = Checked(worse, better).factorize(saddle).solve(b)
    assert np.array_equal(x, better.factorize(saddle).solve(b))
    assert relative_residual(saddle, x, b) > ACCURACY
    x = Checked(better, Perturbed(1e-6)).factorize(saddle).solve(b)
    assert np.array_equal(x, better.factorize(saddle).solve(b))


def test_unchecked_alternative_only_counts(saddle):
    b = np.random.default_rng(3).standard_normal(saddle.shape[0])
    first = Perturbed(1e-9)
    solver = Checked(first, None)
    x = solver.factorize(saddle).solve(b)
    assert np.array_equal(x, first.factorize(saddle).solve(b))
    assert solver.off == 1 and "linear = 'auto' or 'superlu' retries them" in solver.notes()[0]


def test_tiny_systems_are_not_checked():
    a = sp.csr_matrix(np.diag(np.arange(1.0, 11.0)))
    first = Counting()
    first.dense_up_to = linear.DENSE_UP_TO
    solver = Checked(first, Counting())
    factor = solver.factorize(a)
    assert type(factor).__name__ == "_DenseLU" and first.factorizations == 0
    factor.solve(np.ones(10))
    assert solver.solves == 0


@needs_pardiso
def test_pardiso_is_checked_by_itself_without_matching_then_superlu_under_auto_and_alone_by_name():
    auto = linear.make_solver("auto")
    assert isinstance(auto, Checked) and isinstance(auto.first, linear.Pardiso) and auto.first.matching
    assert isinstance(auto.then, Checked) and isinstance(auto.then.first, linear.Pardiso)
    assert not auto.then.first.matching and auto.then.first.name == "pardiso without matching"
    assert isinstance(auto.then.then, linear.SuperLU)
    named = linear.make_solver("pardiso")
    assert isinstance(named, Checked) and isinstance(named.first, linear.Pardiso) and named.then is None
    assert isinstance(linear.make_solver("superlu"), linear.SuperLU)


@needs_pardiso
def test_a_load_step_reaches_pardiso_through_every_wrapper():
    """begin_step (a fresh analysis at a step's first factorization) reaches PARDISO inside a checked
    backend inside a handover, as on a large 3D model under 'auto'."""
    pytest.importorskip("pyamg")
    x3 = np.random.default_rng(0).uniform(size=(10, 3))
    solver = linear.make_solver("auto", x3, linear.AMG_FROM_3D)
    assert isinstance(solver, linear.Handover) and isinstance(solver.then, Checked)
    pardiso = solver.then.first
    a = sp.diags([-1.0, 2.5, -1.0], [-1, 0, 1], shape=(500, 500), format="csr")
    pardiso.factorize(a)
    pardiso.factorize(a)
    assert pardiso.analyses == 1
    solver.begin_step()
    pardiso.factorize(a)
    assert pardiso.analyses == 2


@needs_pardiso
def test_pardiso_without_matching_sets_mkls_defaults_but_scaling_and_matching(saddle):
    """The default backend leaves PARDISO's controls to MKL (iparm(1) = 0, the first version's bits);
    without matching they are MKL's defaults for the type (pardisoinit) with iparm(11) = iparm(13) = 0.
    On the paper's rigid RP saddle point the matching avoids every perturbed pivot; without it some
    are perturbed (iparm(14), PARDISO's own count), and the checked solve still meets the accuracy."""
    b = np.random.default_rng(6).standard_normal(saddle.shape[0])
    plain, bare = linear.Pardiso(), linear.Pardiso(matching=False)
    x = plain.factorize(saddle).solve(b)
    assert relative_residual(saddle, x, b) < 1e-10 and plain._solver.iparm[13] == 0
    assert plain._solver.iparm[10] == plain._solver.iparm[12] == 1  # what MKL chose for itself
    bare.factorize(saddle).solve(b)
    ip = bare._solver.iparm
    assert ip[0] == 1 and ip[10] == 0 and ip[12] == 0 and ip[9] == 13 and ip[7] == 2  # eps 1e-13, 2 refinements
    assert ip[1] == plain._solver.iparm[1]  # MKL's own ordering
    assert ip[13] > 0  # perturbed pivots: the matching really is off
    checked = Checked(linear.Pardiso(matching=False), None)
    y = checked.factorize(saddle).solve(b)
    assert relative_residual(saddle, y, b) <= ACCURACY
    exact = spla.splu(saddle.tocsc()).solve(b)
    assert np.abs(y - exact).max() <= 1e-5 * np.abs(exact).max()
    sym = sp.diags([-1.0, 2.5, -1.0], [-1, 0, 1], shape=(6000, 6000), format="csr")  # symmetric: mtype -2
    bare.factorize(sym)
    assert bare.mtype == -2 and bare._solver.iparm[12] == 0 and bare._solver.iparm[9] == 8  # MKL's -2 defaults


def test_a_chain_of_checked_backends_hands_over_stage_by_stage(saddle):
    """Checked(first, Checked(second, third)), as 'auto' builds it with PARDISO, PARDISO without matching
    and SuperLU: a solve that the first backend gets wrong goes to the second, whose own wrong solves go
    to the third; each stage takes over at the third matrix its fallback solved accurately."""
    b = np.random.default_rng(7).standard_normal(saddle.shape[0])
    first, second, third = Perturbed(1e-9), Perturbed(1e-13), Counting()
    inner = Checked(second, third)
    solver = Checked(first, inner)
    for k in range(1, HAND_OVER_AFTER + 1):  # the second's factors are refined to the accuracy: third not asked
        x = solver.factorize(saddle).solve(b)
        assert relative_residual(saddle, x, b) <= ACCURACY
        assert first.factorizations == k and second.factorizations == k and third.factorizations == 0
    assert "perturbed's solution of a" in solver.handed_over and inner.refined == HAND_OVER_AFTER
    solver.factorize(saddle).solve(b)  # handed over: the first is not asked
    assert first.factorizations == HAND_OVER_AFTER and second.factorizations == HAND_OVER_AFTER + 1
    # the second stage gets them wrong too: the third solves, and takes over from the second at the third
    first, second, third = Perturbed(1e-9), Perturbed(1e-9), Counting()
    inner = Checked(second, third)
    solver = Checked(first, inner)
    for k in range(1, HAND_OVER_AFTER + 2):
        x = solver.factorize(saddle).solve(b)
        assert relative_residual(saddle, x, b) < 1e-12 and third.factorizations == k
    assert solver.handed_over and inner.handed_over and "counting solved from then on" in inner.handed_over
    assert second.factorizations == HAND_OVER_AFTER  # the inner stage's handover: its first backend not asked
    notes = solver.notes()
    assert any("solved from then on" in n and n.startswith("perturbed's solution") for n in notes)
    assert any(n.startswith("perturbed's solution") and "counting solved from then on" in n for n in notes)
