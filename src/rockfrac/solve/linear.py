"""Linear solver backends sharing one verb: ``solve(A, b) -> x`` for CSR matrices."""

from __future__ import annotations

from typing import Protocol

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla


class LinearSolver(Protocol):
    name: str

    def solve(self, a: sp.csr_matrix, b: np.ndarray) -> np.ndarray: ...


class SuperLU:
    """SciPy's SuperLU direct solver (the default; always available)."""

    name = "superlu"

    def solve(self, a: sp.csr_matrix, b: np.ndarray) -> np.ndarray:
        return spla.spsolve(a.tocsc(), b)


SOLVERS = {"superlu": SuperLU}


def make_solver(name: str) -> LinearSolver:
    """Backend by name; raises ValueError listing the available ones."""
    try:
        return SOLVERS[name]()
    except KeyError:
        raise ValueError(f"unknown linear solver {name!r}; available: {sorted(SOLVERS)}") from None
