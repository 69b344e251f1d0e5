"""Linear solver backends sharing one verb: ``solve(A, b) -> x`` for CSR matrices.

``factorize(A)`` returns an object whose ``solve(b)`` reuses the factorization (path following
needs two right-hand sides per iteration).
"""

from __future__ import annotations

from typing import Protocol

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla


class Factorization(Protocol):
    def solve(self, b: np.ndarray) -> np.ndarray: ...


class LinearSolver(Protocol):
    name: str

    def factorize(self, a: sp.csr_matrix) -> Factorization: ...

    def solve(self, a: sp.csr_matrix, b: np.ndarray) -> np.ndarray: ...


class SuperLU:
    """SciPy's SuperLU direct solver (the default; always available)."""

    name = "superlu"

    def factorize(self, a: sp.csr_matrix) -> Factorization:
        return spla.splu(a.tocsc())

    def solve(self, a: sp.csr_matrix, b: np.ndarray) -> np.ndarray:
        return self.factorize(a).solve(b)


SOLVERS = {"superlu": SuperLU}


def make_solver(name: str) -> LinearSolver:
    """Backend by name; raises ValueError listing the available ones."""
    try:
        return SOLVERS[name]()
    except KeyError:
        raise ValueError(f"unknown linear solver {name!r}; available: {sorted(SOLVERS)}") from None
