"""Sparse assembly: a CSR pattern built once, Numba scatter of element blocks into its slots."""

from __future__ import annotations

from dataclasses import dataclass

import numba as nb
import numpy as np
import scipy.sparse as sp


@dataclass
class Pattern:
    """CSR sparsity pattern of the global matrix and, per element group, the slot of each entry.

    slots[g]: (n_el, nd, nd) indices into ``data`` for the element blocks of group g.
    """

    n: int
    indptr: np.ndarray
    indices: np.ndarray
    slots: list[np.ndarray]

    @classmethod
    def build(cls, n: int, groups: list[np.ndarray]) -> Pattern:
        """Pattern of an n x n matrix receiving dense blocks on the dof lists ``groups`` (n_el, nd)."""
        keys = []
        for dofs in groups:
            nd = dofs.shape[1]
            rows = np.repeat(dofs, nd, axis=1).astype(np.int64)
            cols = np.tile(dofs, (1, nd)).astype(np.int64)
            keys.append((rows * n + cols).ravel())
        diag = np.arange(n, dtype=np.int64) * (n + 1)  # every dof keeps a diagonal slot
        all_keys = np.sort(np.concatenate(keys + [diag]))  # sort + neighbour test: ~10x np.unique's hashing
        all_keys = all_keys[np.concatenate(([True], all_keys[1:] != all_keys[:-1]))]
        rows = all_keys // n
        indices = (all_keys - rows * n).astype(np.int32 if n < 2**31 else np.int64)
        indptr = np.zeros(n + 1, dtype=np.int64)
        np.cumsum(np.bincount(rows, minlength=n), out=indptr[1:])
        slots = []
        kind = np.int32 if all_keys.size < 2**31 else np.int64  # half the memory traffic of the scatter
        for dofs, k in zip(groups, keys):
            nd = dofs.shape[1]
            slots.append(np.searchsorted(all_keys, k).astype(kind).reshape(-1, nd, nd))
        return cls(n=n, indptr=indptr, indices=indices, slots=slots)

    @property
    def nnz(self) -> int:
        return int(self.indptr[-1])

    def matrix(self, data: np.ndarray) -> sp.csr_matrix:
        """CSR matrix sharing this pattern (no copy of the index arrays)."""
        return sp.csr_matrix((data, self.indices, self.indptr), shape=(self.n, self.n), copy=False)

    def positions(self, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Data positions of every entry in ``rows`` or in the columns ``rows``, and of their diagonals."""
        mark = np.zeros(self.n, dtype=bool)
        mark[rows] = True
        row_of = np.repeat(np.arange(self.n), np.diff(self.indptr))
        hit = np.flatnonzero(mark[row_of] | mark[self.indices])
        is_diag = np.flatnonzero(mark[row_of] & (row_of == self.indices))
        return hit, is_diag


@nb.njit(cache=True)
def scatter_matrix(data: np.ndarray, slots: np.ndarray, ke: np.ndarray) -> None:
    """data[slots] += ke for element blocks ke (n_el, nd, nd); serial, memory bound."""
    n_el, nd, _ = ke.shape
    for e in range(n_el):
        for i in range(nd):
            for j in range(nd):
                data[slots[e, i, j]] += ke[e, i, j]


@nb.njit(cache=True)
def scatter_vector(f: np.ndarray, dofs: np.ndarray, fe: np.ndarray) -> None:
    """f[dofs] += fe for element vectors fe (n_el, nd)."""
    n_el, nd = fe.shape
    for e in range(n_el):
        for i in range(nd):
            f[dofs[e, i]] += fe[e, i]
