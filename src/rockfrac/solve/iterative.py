"""Iterative solving: GMRES preconditioned by smoothed-aggregation AMG (pyamg), the rigid-body
modes of a 3D mesh as its near-null space, and the hand-over to a direct backend at a failure."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from rockfrac.solve.backend import Factorization, SolverFailed, _Backend, relative_residual

class _KrylovSolve:
    """GMRES on a with a preconditioner, applied from the left (SciPy's M) or, ``right``, as GMRES
    on a M (then x = M y): the saddle points' block preconditioner stagnates from the left, where
    SciPy measures the preconditioned residual of a badly scaled system."""

    def __init__(self, a: sp.csr_matrix, precondition, rtol: float, maxiter: int, restart: int,
                 right: bool = False):
        self._a, self._m, self._right = a, precondition, right
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
            if self._right:
                m, a = self._m, self._a
                am = spla.LinearOperator(a.shape, matvec=lambda v: a @ m(v), dtype=float)
                y, info = spla.gmres(am, b, rtol=self._rtol, atol=0.0, restart=self._restart,
                                     maxiter=self._maxiter, callback=counter, callback_type="pr_norm")
                x = m(y)
            else:
                x, info = spla.gmres(self._a, b, M=self._m, rtol=self._rtol, atol=0.0, restart=self._restart,
                                     maxiter=self._maxiter, callback=counter, callback_type="pr_norm")
        self.iterations = count[0]
        res = relative_residual(self._a, x, b)
        if not res <= 10 * self._rtol:  # the true residual (GMRES's own estimate may stall short of it)
            raise SolverFailed(f"GMRES did not converge: relative residual {res:.2e} after "
                               f"{count[0]} iterations (tolerance {self._rtol:.0e})")
        return x


class KrylovAMG(_Backend):
    """Restarted GMRES preconditioned by one V-cycle of smoothed-aggregation AMG (pyamg).

    The AMG works on nodal blocks (2 x 2, or 3 x 3 given the nodes of a 3D mesh) with the rigid
    translations as near-null space, and in 3D the three rotations about the centroid too. Given
    the mesh's nodes (``coordinates`` (n_nodes, dim)), a tangent larger than the displacement dofs
    carries multipliers (the RP CSE's saddle points, numbered after the displacements): it is
    preconditioned block-triangularly, AMG on the displacement block and a direct solve of an
    approximate Schur complement (:mod:`rockfrac.solve.saddle`). Iterative: relative residual
    1e-11, far below Newton's 1e-8, or ``SolverFailed``.
    """

    name = "gmres-amg"
    rtol = 1e-11
    restart = 60
    maxiter = 10  # restarts: at most 600 GMRES iterations
    block = 2  # displacement components per node without coordinates

    def __init__(self, coordinates: np.ndarray | None = None) -> None:
        import pyamg  # noqa: F401

        self._coordinates = coordinates
        if coordinates is not None:
            self.block = coordinates.shape[1]

    def _near_null(self, n: int) -> np.ndarray:
        x = self._coordinates
        if x is not None and x.shape[1] == 3 and n == 3 * x.shape[0]:
            return rigid_modes_3d(x)
        k = self.block
        translations = np.zeros((n, k))
        for c in range(k):
            translations[c::k, c] = 1.0
        return translations

    def _amg(self, a: sp.csr_matrix):
        """One V-cycle of smoothed aggregation on the displacement block a, as a callable."""
        import pyamg

        n, k = a.shape[0], self.block
        try:
            with np.errstate(all="ignore"):
                if n % k == 0:
                    ml = pyamg.smoothed_aggregation_solver(a.tobsr(blocksize=(k, k)), B=self._near_null(n),
                                                           symmetry="nonsymmetric", max_coarse=500)
                else:
                    ml = pyamg.smoothed_aggregation_solver(a, symmetry="nonsymmetric", max_coarse=500)
        except Exception as err:  # noqa: BLE001 -- pyamg raises assorted errors on bad matrices
            raise SolverFailed(f"AMG set-up failed: {err}") from err
        return ml.aspreconditioner(cycle="V")

    def _factorize(self, a: sp.csr_matrix) -> Factorization:
        a = sp.csr_matrix(a)
        n = a.shape[0]
        n_u = n if self._coordinates is None else self._coordinates.size
        if n <= n_u:
            return _KrylovSolve(a, self._amg(a), self.rtol, self.maxiter, self.restart)
        from rockfrac.solve.saddle import BlockTriangular

        pre = BlockTriangular(a, n_u, self.block, self._amg)
        return _KrylovSolve(a, pre, self.rtol, self.maxiter, self.restart, right=True)


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
