"""The linear-solver contract (``factorize(A).solve(b)``, ``SolverFailed``), the dense path of tiny
systems, SciPy's SuperLU, and the symmetry check of a CSR matrix (see rockfrac.solve.linear)."""

from __future__ import annotations

from typing import Protocol

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from rockfrac.compiled import kernel
from rockfrac.fem.assembly import lower_bound

DENSE_UP_TO = 128  # rows up to which the direct backends factorize densely (crossover ~170: "Tiny systems")


class SolverFailed(RuntimeError):
    """A backend could not solve: a failed factorization or a Krylov method that did not converge."""


class Factorization(Protocol):
    def solve(self, b: np.ndarray) -> np.ndarray: ...


class LinearSolver(Protocol):
    name: str

    def begin_step(self) -> None:
        """A load step starts (a backend may refresh per-step data: PARDISO's analysis)."""

    def notes(self) -> list[str]:
        """What the run's log should say about the backend's solves (a handover, inaccurate solves)."""

    def factorize(self, a: sp.csr_matrix) -> Factorization: ...

    def solve(self, a: sp.csr_matrix, b: np.ndarray) -> np.ndarray: ...


def relative_residual(a: sp.csr_matrix, x: np.ndarray, b: np.ndarray) -> float:
    """||b - A x|| / ||b|| (2-norms over all columns; ||b - A x|| where b = 0); inf if x is not finite
    or A x overflows (a solve off by 1e150 and more: a NaN here would compare as no worse than any)."""
    if not np.all(np.isfinite(x)):
        return float("inf")
    with np.errstate(over="ignore", invalid="ignore"):
        r = np.linalg.norm(np.asarray(b).reshape(x.shape) - a @ x)
        nb = np.linalg.norm(b)
        res = r / nb if nb > 0 else r
    return float(res) if np.isfinite(res) else float("inf")


class _DenseLU:
    """LU with partial pivoting of a small matrix held dense (LAPACK getrf / getrs), and one step
    of iterative refinement per solve (as PARDISO does): the RP saddle points mix entries of 1e7
    and 1e-2, where plain LU leaves an error that costs Newton an extra iteration."""

    def __init__(self, a: sp.csr_matrix):
        from scipy.linalg import lapack

        self._a = a.toarray()
        if not np.isfinite(self._a).all():
            raise SolverFailed("matrix has non-finite entries")
        self._lu, self._piv, info = lapack.dgetrf(self._a)
        if info > 0:
            raise SolverFailed(f"matrix is singular (dense LU: zero pivot in column {info})")
        self._getrs = lapack.dgetrs

    def _substitute(self, b: np.ndarray) -> np.ndarray:
        x, info = self._getrs(self._lu, self._piv, b)
        if info != 0:
            raise SolverFailed(f"dense LU solve failed (LAPACK info {info})")
        return x

    def solve(self, b: np.ndarray) -> np.ndarray:
        x = self._substitute(b)
        return x + self._substitute(b - self._a @ x)


class _Backend:
    """``solve`` as a factorization used once; systems of at most ``dense_up_to`` rows are
    factorized densely (LAPACK), which every direct backend shares: on the paper's 16-24-dof
    systems a sparse solver's set-up per call is 20x the arithmetic (benchmarks/README.md, "Tiny
    systems"). 0 switches it off."""

    name = ""
    dense_up_to = 0

    def begin_step(self) -> None:
        return None

    def notes(self) -> list[str]:
        return []

    def factorize(self, a: sp.csr_matrix) -> Factorization:
        if a.shape[0] <= self.dense_up_to:
            return _DenseLU(a)
        return self._factorize(a)

    def _factorize(self, a: sp.csr_matrix) -> Factorization:
        raise NotImplementedError

    def solve(self, a: sp.csr_matrix, b: np.ndarray) -> np.ndarray:
        return self.factorize(a).solve(b)


class SuperLU(_Backend):
    """SciPy's SuperLU direct solver (always available)."""

    name = "superlu"
    dense_up_to = DENSE_UP_TO

    def _factorize(self, a: sp.csr_matrix) -> Factorization:
        return spla.splu(a.tocsc())


@kernel
def is_symmetric(indptr, indices, data, rel_tol):
    """|a_ij - a_ji| <= rel_tol max |a| for every entry of a CSR matrix with sorted rows (a missing
    mirror entry counts as 0), all entries finite and not all zero; stops at the first that is not."""
    n = indptr.shape[0] - 1
    scale = 0.0
    for q in range(data.shape[0]):
        v = abs(data[q])
        if not v < np.inf:
            return False
        if v > scale:
            scale = v
    if scale == 0.0:
        return False
    tol = rel_tol * scale
    for i in range(n):
        for q in range(indptr[i], indptr[i + 1]):
            j = indices[q]
            if j <= i:
                continue
            lo = lower_bound(indices, indptr[j], indptr[j + 1], i)  # a_ji by bisection in row j
            mirror = data[lo] if lo < indptr[j + 1] and indices[lo] == i else 0.0
            if not abs(data[q] - mirror) <= tol:
                return False
    # entries below the diagonal without a mirror above
    for i in range(n):
        for q in range(indptr[i], indptr[i + 1]):
            j = indices[q]
            if j >= i:
                break
            lo = lower_bound(indices, indptr[j], indptr[j + 1], i)
            if not (lo < indptr[j + 1] and indices[lo] == i) and not abs(data[q]) <= tol:
                return False
    return True
