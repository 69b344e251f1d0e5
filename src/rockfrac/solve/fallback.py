"""Backends made of two: one that hands over to another, for the rest of the run, when it fails
(``Handover``), and one whose every solve is checked against its equations, refined with its own
factors where it is not accurate, and retried by another where that is not enough (``Checked``).
Both forward ``begin_step`` and report what happened in ``notes()`` (the run's log)."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from rockfrac.solve.backend import Factorization, LinearSolver, SolverFailed, _DenseLU, relative_residual

# The relative residual ||b - A x|| / ||b|| above which ``Checked`` retries a solve. PARDISO met 3e-9
# or better on every well-posed system of the test suite (39647 solves, RP and EP surfaces, 2D and
# 3D, embedded bands); on RP surfaces on every edge of a disc its static pivoting perturbs hundreds
# of pivots and leaves 1e-3 to 1 (median 3e-2), where SuperLU meets 1e-12 (benchmarks/README.md,
# "Fragmentation"). A Newton correction this accurate costs no extra iteration (tolerance 1e-8).
ACCURACY = 1e-6

# Before another backend is asked, an inaccurate solution is refined with the first backend's own
# factors (x += A^-1 (b - A x)) while each step at least halves the residual, at most this often. A
# factorization whose pivots were perturbed only slightly (PARDISO's on the grains' RP saddle point:
# 8.3e-6 after its own refinement) so meets the accuracy at the cost of a few substitutions, and keeps
# its backend (two MKL threads) where SuperLU (one) would have solved the rest of the run; one whose
# perturbation is not small (the disc's RP, 1e-3 to 1) stops refining at the first step.
REFINE_STEPS = 5

# A solution within ``ACCURACY`` whose relative residual is still above this is refined the same way
# (each step kept only if it at least halves the residual). Newton's energy test weighs the multiplier
# rows of an RP saddle point by the multipliers: on unyielded RP surfaces on every face of a 2 x 2 x 2
# hex box (junctions round every internal edge) MKL 2026.2's PARDISO perturbed one pivot and left
# 9e-11, whose energy (5e-10 of the first) cost a third iteration of a linear problem; one
# substitution more brought it to 7e-13, SuperLU's level, and the second iteration converges.
POLISH = 1e-12

# ``then`` takes over for the rest of the run at the third matrix whose solve ``first`` got wrong (and
# refinement could not mend) where ``then``'s was accurate; the two before, ``then`` solves that matrix
# only. PARDISO on the grains' RP saddle point was off beyond repair at one factorization in 36 (2e1,
# after 3 others were refined within 1e-6), and that one handed the rest of the run to SuperLU, whose
# factorization on one thread costs 2-3 times PARDISO's on two (the disc). There it took over at the
# 38th solve all the same; on the disc's RP nearly every solve is off, and it hands over at once.
HAND_OVER_AFTER = 3


class Handover:
    """An iterative backend that hands over to a direct one, for the rest of the run, at its first
    failure (a factorization or a solve that raises SolverFailed): ``auto``'s 3D choice."""

    def __init__(self, first: LinearSolver, then: LinearSolver):
        self.first, self.then = first, then
        self.name = f"{first.name}, then {then.name} if it fails"
        self.failed = ""  # why the first backend was given up ("" while it is used)

    def begin_step(self) -> None:
        self.first.begin_step()
        self.then.begin_step()

    def notes(self) -> list[str]:
        own = [f"{self.first.name} failed ({self.failed}); {self.then.name} solved from then on"] if self.failed else []
        return own + self.first.notes() + self.then.notes()

    def factorize(self, a: sp.csr_matrix) -> Factorization:
        if not self.failed:
            try:
                return _HandoverFactor(self, self.first.factorize(a), a)
            except SolverFailed as err:
                self.failed = str(err)
        return self.then.factorize(a)

    def solve(self, a: sp.csr_matrix, b: np.ndarray) -> np.ndarray:
        return self.factorize(a).solve(b)


class _HandoverFactor:
    def __init__(self, owner: Handover, factor: Factorization, a: sp.csr_matrix):
        self._owner, self._factor, self._a = owner, factor, a

    def solve(self, b: np.ndarray) -> np.ndarray:
        if not self._owner.failed:
            try:
                return self._factor.solve(b)
            except SolverFailed as err:
                self._owner.failed = str(err)
                self._factor = self._owner.then.factorize(self._a)
        return self._factor.solve(b)


class Checked:
    """A direct backend whose every sparse solve is checked against its equations: a solution that
    leaves a relative residual above ``accuracy`` is refined with ``first``'s factors (at most
    REFINE_STEPS steps, each at least halving the residual) and, where that does not reach the
    accuracy, solved again by ``then`` (its factors of that matrix). Once ``then``'s solution has met
    the accuracy where ``first``'s did not at HAND_OVER_AFTER matrices, ``then`` solves for the rest of
    the run (``first`` fails on this problem's matrices, e.g. PARDISO's static pivoting on RP saddle
    points); where ``then``'s does not meet it either, the system is singular to working precision
    for that right-hand side (a mechanism under path control's load pattern) and the solution with
    the smaller residual is returned, ``first`` kept. A solution within ``accuracy`` but above
    POLISH is refined the same way towards round-off (kept step by step where it halves).
    With ``then = None`` solves are only counted. Dense (tiny) systems are not checked: every direct
    backend factorizes them alike (LAPACK, with refinement)."""

    def __init__(self, first: LinearSolver, then: LinearSolver | None, accuracy: float = ACCURACY):
        self.first, self.then, self.accuracy = first, then, accuracy
        self.name = first.name + (f", checked (then {then.name} where its solves are off)" if then else ", checked")
        self.handed_over = ""  # why ``then`` took over ("" while ``first`` solves)
        self.retried = 0  # matrices whose solve ``then`` made accurate where ``first``'s was not
        self.solves = 0  # solves checked
        self.off = 0  # of them above ``accuracy``
        self.refined = 0  # of those, brought within ``accuracy`` by refinement with first's factors
        self.refine_steps = 0  # the refinement steps those took
        self.worst = 0.0  # the largest relative residual of ``first``'s solutions
        self.polished = 0  # solves within ``accuracy`` brought nearer round-off (POLISH) by refinement

    def begin_step(self) -> None:
        self.first.begin_step()
        if self.then is not None:
            self.then.begin_step()

    def notes(self) -> list[str]:
        out = []
        if self.off:
            out.append(f"{self.off} of {self.solves} solves by {self.first.name} left relative residuals above "
                       f"{self.accuracy:g} (the largest {self.worst:.1e})"
                       + ("" if self.then is not None else "; [solver] linear = 'auto' or 'superlu' retries them"))
        if self.polished:
            out.append(f"{self.polished} of {self.solves} solves by {self.first.name} within {self.accuracy:g} were "
                       f"refined towards round-off ({POLISH:g}) with their own factors")
        if self.refined:
            out.append(f"{self.refined} of them met it after iterative refinement with {self.first.name}'s factors "
                       f"({self.refine_steps} substitutions in all)")
        if self.retried and not self.handed_over and self.then is not None:
            out.append(f"{self.then.name} solved {self.retried} of them again, accurately, "
                       f"with its factors of that matrix ({self.first.name} kept)")
        if self.handed_over:
            out.append(self.handed_over)
        return out + self.first.notes() + (self.then.notes() if self.then is not None else [])

    def factorize(self, a: sp.csr_matrix) -> Factorization:
        if self.handed_over and self.then is not None:
            return self.then.factorize(a)
        factor = self.first.factorize(a)
        if isinstance(factor, _DenseLU):
            return factor
        # the values are copied: the caller may reuse its arrays while the factor lives
        return _CheckedFactor(self, factor, sp.csr_matrix((a.data.copy(), a.indices, a.indptr), shape=a.shape))

    def solve(self, a: sp.csr_matrix, b: np.ndarray) -> np.ndarray:
        return self.factorize(a).solve(b)


class _CheckedFactor:
    def __init__(self, owner: Checked, factor: Factorization, a: sp.csr_matrix):
        self._owner, self._factor, self._a = owner, factor, a
        self._retry: Factorization | None = None  # ``then``'s factors of the same matrix, once made
        self._switched = False

    def solve(self, b: np.ndarray) -> np.ndarray:
        owner = self._owner
        x = self._factor.solve(b)
        if self._switched:
            return x
        res = relative_residual(self._a, x, b)
        owner.solves += 1
        owner.worst = max(owner.worst, res)
        if res <= owner.accuracy:
            if res > POLISH:
                x, res_polished, steps = _refined(self._factor, self._a, b, x, res, POLISH)
                owner.polished += res_polished < res
            return x
        owner.off += 1
        x, res, steps = _refined(self._factor, self._a, b, x, res, owner.accuracy)
        if res <= owner.accuracy:
            owner.refined += 1
            owner.refine_steps += steps
            return x
        if owner.then is None:
            return x
        try:
            if self._retry is None:
                self._retry = owner.then.factorize(self._a)
            y = self._retry.solve(b)
        except RuntimeError:  # SolverFailed, or SuperLU's "exactly singular": first's solution stands
            return x
        res_then = relative_residual(self._a, y, b)
        if res_then <= owner.accuracy:
            owner.retried += 1
            if owner.retried >= HAND_OVER_AFTER:
                owner.handed_over = (f"{owner.first.name}'s solution of a {self._a.shape[0]}-row system left a "
                                     f"relative residual of {res:.1e} where {owner.then.name}'s met {owner.accuracy:g} "
                                     f"({res_then:.1e}), the {_ordinal(owner.retried)} such system; "
                                     f"{owner.then.name} solved from then on")
            self._factor, self._switched = self._retry, True  # this matrix's other solves: then's factors
            return y
        return y if res_then < res else x


def _refined(factor: Factorization, a: sp.csr_matrix, b: np.ndarray, x: np.ndarray, res: float,
             accuracy: float) -> tuple[np.ndarray, float, int]:
    """Iterative refinement of ``x`` (relative residual ``res``) with ``factor``: up to REFINE_STEPS
    corrections, each kept only if it at least halves the residual, until ``accuracy`` is met.
    Returns the best solution, its residual and the steps kept."""
    steps = 0
    while steps < REFINE_STEPS and res > accuracy:
        trial = x + factor.solve(np.asarray(b).reshape(x.shape) - a @ x)
        res_trial = relative_residual(a, trial, b)
        if not (res_trial < res and res_trial <= 0.5 * res):  # not contracting (or inf): the factors are too far off
            break
        x, res, steps = trial, res_trial, steps + 1
    return x, res, steps


def _ordinal(n: int) -> str:
    """1st, 2nd, 3rd, 4th..."""
    return f"{n}" + ("th" if 10 <= n % 100 <= 20 else {1: "st", 2: "nd", 3: "rd"}.get(n % 10, "th"))
