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


class _PardisoFactor:
    def __init__(self, solver, a: sp.csr_matrix):
        self._solver, self._a = solver, a

    def solve(self, b: np.ndarray) -> np.ndarray:
        return self._solver.solve(self._a, b)


class Pardiso:
    """Intel MKL PARDISO through pypardiso (optional: ``pip install pypardiso``), unsymmetric mode.

    One PARDISO instance serves the whole run: each factorization first frees the previous one's
    factors (MKL would otherwise keep every factorization alive: memory grows by the size of a
    factorization per Newton iteration), and the instance's set-up cost is paid once.
    """

    name = "pardiso"

    def __init__(self) -> None:
        import pypardiso  # noqa: F401  (fails here, not mid-run, if it is missing)

        self._solver = None

    def factorize(self, a: sp.csr_matrix) -> Factorization:
        import pypardiso

        if self._solver is None:
            self._solver = pypardiso.PyPardisoSolver(mtype=11)
            self._solver.set_statistical_info_off()
        else:
            self._solver.free_memory(everything=False)  # release the last factors
        a = sp.csr_matrix(a)
        self._solver.factorize(a)  # explicit: never a stale factorization of an equal-looking matrix
        return _PardisoFactor(self._solver, a)

    def solve(self, a: sp.csr_matrix, b: np.ndarray) -> np.ndarray:
        return self.factorize(a).solve(b)

    def __del__(self) -> None:
        if getattr(self, "_solver", None) is not None:
            try:
                self._solver.free_memory(everything=True)
            except Exception:  # noqa: BLE001 -- at interpreter shutdown scipy may already be gone
                pass


SOLVERS = {"superlu": SuperLU, "pardiso": Pardiso}


def available() -> list[str]:
    """Names of the backends that can be used on this machine."""
    names = []
    for name, cls in SOLVERS.items():
        try:
            cls()
        except ImportError:
            continue
        names.append(name)
    return names


PREFERENCE = ("pardiso", "superlu")  # fastest first, measured in benchmarks/README.md


def make_solver(name: str) -> LinearSolver:
    """Backend by name ('auto': the fastest installed); raises ValueError listing the available ones."""
    if name == "auto":
        installed = available()
        return SOLVERS[next(n for n in PREFERENCE if n in installed)]()
    if name not in SOLVERS:
        raise ValueError(f"unknown linear solver {name!r}; known: {sorted(SOLVERS)}")
    try:
        return SOLVERS[name]()
    except ImportError as err:
        raise ValueError(f"linear solver {name!r} is not installed here ({err}); available: {available()}") from None
