"""A block preconditioner for tangents with multiplier rows (the RP CSE's saddle points).

The engine numbers the displacement dofs first, then the multipliers: the tangent is
[[A, B1], [B2, C]], A the displacement block (the bulk plus the augmented pairs r B^T W B), B1, B2
the couplings to the multipliers, C their own block (zero while a point is constrained, eq. 33;
the law's return where it yields). The preconditioner is block upper-triangular,

    P^-1 [r_u, r_l] = [A~^-1 (r_u - B1 y), y],   y = S~^-1 r_l,   S~ = C - B2 D^-1 B1,

A~^-1 one V-cycle of smoothed-aggregation AMG on A (rigid-body modes), D the nodal 3 x 3 (2 x 2)
block diagonal of A: with nodal integration every multiplier couples one node pair, so S~ is as
sparse as C plus the pairs' blocks and is factorized directly (its size is the multipliers').
For a large augmentation S~ tends to the exact Schur complement up to a factor near 2 on the
constrained pairs (D holds r W on both nodes of a pair), which GMRES absorbs.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from rockfrac.solve.backend import SolverFailed


def block_diagonal_inverse(a: sp.csr_matrix, k: int) -> sp.bsr_matrix:
    """The inverse of the k x k nodal block diagonal of a (n, n), n a multiple of k, as a BSR matrix.
    A singular block (no stiffness at a node) raises SolverFailed."""
    n = a.shape[0]
    m = n // k
    rows = np.repeat(np.arange(n), np.diff(a.indptr))
    cols = a.indices
    same = rows // k == cols // k
    blocks = np.zeros((m, k, k))
    np.add.at(blocks, (rows[same] // k, rows[same] % k, cols[same] % k), a.data[same])
    try:
        inverse = np.linalg.inv(blocks)
    except np.linalg.LinAlgError as err:
        raise SolverFailed(f"a singular {k} x {k} nodal block in the displacement block: {err}") from err
    return sp.bsr_matrix((inverse, np.arange(m), np.arange(m + 1)), shape=(n, n))


class BlockTriangular:
    """The preconditioner above as a LinearOperator's matvec (n_u displacement dofs first)."""

    def __init__(self, a: sp.csr_matrix, n_u: int, k: int, amg_of):
        a = sp.csr_matrix(a)
        self.n_u = n_u
        self.a_uu = a[:n_u, :n_u].tocsr()
        self.b1 = a[:n_u, n_u:].tocsr()
        b2 = a[n_u:, :n_u].tocsr()
        c = a[n_u:, n_u:].tocsr()
        schur = (c - b2 @ (block_diagonal_inverse(self.a_uu, k) @ self.b1)).tocsc()
        try:
            self._schur = spla.splu(schur)
        except RuntimeError as err:  # singular: a multiplier with no coupling and no diagonal
            raise SolverFailed(f"the multipliers' approximate Schur complement is singular: {err}") from err
        self._amg = amg_of(self.a_uu)

    def __call__(self, r: np.ndarray) -> np.ndarray:
        y = self._schur.solve(r[self.n_u:])
        x = self._amg(r[: self.n_u] - self.b1 @ y)
        return np.concatenate([x, y])
