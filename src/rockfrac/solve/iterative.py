"""Iterative solving: GMRES preconditioned by smoothed-aggregation AMG (pyamg), the rigid-body
modes of a 3D mesh as its near-null space, and the hand-over to a direct backend at a failure."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from rockfrac.solve.backend import Factorization, LinearSolver, SolverFailed, _Backend

class _KrylovSolve:
    def __init__(self, a: sp.csr_matrix, precondition, rtol: float, maxiter: int, restart: int):
        self._a, self._m = a, precondition
        self._rtol, self._maxiter, self._restart = rtol, maxiter, restart
        self.iterations = 0

    def solve(self, b: np.ndarray) -> np.ndarray:
        norm_b = float(np.linalg.norm(b))
        if norm_b == 0.0:
            return np.zeros_like(b)
        count = [0]

        def counter(_):
            count[0] += 1

        with np.errstate(all="ignore"):
            x, info = spla.gmres(self._a, b, M=self._m, rtol=self._rtol, atol=0.0, restart=self._restart,
                                 maxiter=self._maxiter, callback=counter, callback_type="pr_norm")
        self.iterations = count[0]
        res = float(np.linalg.norm(b - self._a @ x)) / norm_b if np.all(np.isfinite(x)) else np.inf
        if info != 0 or not res <= 10 * self._rtol:
            raise SolverFailed(f"GMRES did not converge: relative residual {res:.2e} after "
                               f"{count[0]} iterations (tolerance {self._rtol:.0e})")
        return x


class KrylovAMG(_Backend):
    """Restarted GMRES preconditioned by one V-cycle of smoothed-aggregation AMG (pyamg).

    The AMG works on 2 x 2 nodal blocks with the two rigid translations as near-null space (the
    engine numbers two displacement components per node first; a matrix of odd size falls back to
    scalar aggregation). Given the nodes of a 3D mesh (``coordinates`` (n_nodes, 3)), on 3 x 3 blocks
    with the six rigid-body modes (three translations, three rotations about the centroid) when the
    matrix has exactly the displacement dofs. Iterative: relative residual 1e-11, far below Newton's
    1e-8, or ``SolverFailed``. Saddle-point tangents (the RP CSE's multiplier rows) defeat it.
    """

    name = "gmres-amg"
    rtol = 1e-11
    restart = 60
    maxiter = 10  # restarts: at most 600 GMRES iterations
    block = 2  # displacement components per node

    def __init__(self, coordinates: np.ndarray | None = None) -> None:
        import pyamg  # noqa: F401

        self._modes = None if coordinates is None or coordinates.shape[1] != 3 else rigid_modes_3d(coordinates)

    def _factorize(self, a: sp.csr_matrix) -> Factorization:
        import pyamg

        a = sp.csr_matrix(a)
        n, k = a.shape[0], self.block
        try:
            with np.errstate(all="ignore"):
                if self._modes is not None and n == self._modes.shape[0]:
                    ml = pyamg.smoothed_aggregation_solver(a.tobsr(blocksize=(3, 3)), B=self._modes,
                                                           symmetry="nonsymmetric", max_coarse=500)
                elif n % k == 0:
                    translations = np.zeros((n, k))
                    for c in range(k):
                        translations[c::k, c] = 1.0
                    ml = pyamg.smoothed_aggregation_solver(a.tobsr(blocksize=(k, k)), B=translations,
                                                           symmetry="nonsymmetric", max_coarse=500)
                else:
                    ml = pyamg.smoothed_aggregation_solver(a, symmetry="nonsymmetric", max_coarse=500)
            precondition = ml.aspreconditioner(cycle="V")
        except Exception as err:  # noqa: BLE001 -- pyamg raises assorted errors on bad matrices
            raise SolverFailed(f"AMG set-up failed: {err}") from err
        return _KrylovSolve(a, precondition, self.rtol, self.maxiter, self.restart)


def rigid_modes_3d(x: np.ndarray) -> np.ndarray:
    """The six rigid-body displacement modes (3 n, 6) of nodes x (n, 3) [m]: translations, then
    rotations about the centroid (scaled to the size of the body), dofs node by node."""
    c = x - x.mean(axis=0)
    c = c / max(float(np.abs(c).max()), 1e-300)
    n = x.shape[0]
    b = np.zeros((n, 3, 6))
    for i in range(3):
        b[:, i, i] = 1.0
    b[:, 1, 3], b[:, 2, 3] = -c[:, 2], c[:, 1]  # about x
    b[:, 0, 4], b[:, 2, 4] = c[:, 2], -c[:, 0]  # about y
    b[:, 0, 5], b[:, 1, 5] = -c[:, 1], c[:, 0]  # about z
    return b.reshape(3 * n, 6)


class Handover:
    """An iterative backend that hands over to a direct one, for the rest of the run, at its first
    failure (a factorization or a solve that raises SolverFailed): ``auto``'s 3D choice."""

    def __init__(self, first: LinearSolver, then: LinearSolver):
        self.first, self.then = first, then
        self.name = f"{first.name}, then {then.name} if it fails"
        self.failed = ""  # why the first backend was given up ("" while it is used)

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
