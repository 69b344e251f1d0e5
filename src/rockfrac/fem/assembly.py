"""Sparse assembly: a CSR pattern built once, Numba scatter of element blocks into its slots."""

from __future__ import annotations

from dataclasses import dataclass

import numba as nb
import numpy as np
import scipy.sparse as sp

from rockfrac.compiled import inner, kernel
from rockfrac.threads import parallel_kernel


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
        """Pattern of an n x n matrix receiving dense blocks on the dof lists ``groups`` (n_el, nd).

        Row by row (compiled, no global sort): each row's columns are the dofs of the elements that
        hold it, sorted and made unique, plus its diagonal; each element entry's slot is found in its
        row by bisection. The same arrays as :meth:`build_sorted` (tested).
        """
        groups = [np.asarray(g) for g in groups]
        if any(g.size and (g.min() < 0 or g.max() >= n) for g in groups):
            raise ValueError(f"element dofs outside 0..{n - 1}")
        counts = np.array([g.shape[0] for g in groups], dtype=np.int64)
        nds = np.array([g.shape[1] if g.ndim == 2 else 0 for g in groups], dtype=np.int64)
        flat = np.concatenate([g.ravel().astype(np.int64) for g in groups] + [np.zeros(0, np.int64)])
        nd_of = np.repeat(nds, counts)  # per element, over all groups
        start = np.zeros(nd_of.size + 1, dtype=np.int64)
        np.cumsum(nd_of, out=start[1:])
        slot_start = np.zeros(nd_of.size + 1, dtype=np.int64)
        np.cumsum(nd_of * nd_of, out=slot_start[1:])
        inc_ptr, inc_el, inc_i, width = _incidence(n, flat, start, nd_of)
        lengths = _row_lengths(inc_ptr, inc_el, flat, start, nd_of, width)
        indptr = np.zeros(n + 1, dtype=np.int64)
        np.cumsum(lengths, out=indptr[1:])
        nnz = int(indptr[-1])
        indices = np.empty(nnz, dtype=np.int32 if n < 2**31 else np.int64)
        slots_flat = np.empty(int(slot_start[-1]), dtype=np.int32 if nnz < 2**31 else np.int64)
        _fill_rows(inc_ptr, inc_el, inc_i, flat, start, nd_of, slot_start, width, indptr, indices, slots_flat)
        slots, k = [], 0
        offsets = np.concatenate(([0], np.cumsum(counts)))
        for g, nd in zip(groups, nds):
            a, b = slot_start[offsets[k]], slot_start[offsets[k + 1]]
            slots.append(slots_flat[a:b].reshape(g.shape[0], int(nd), int(nd)))
            k += 1
        return cls(n=n, indptr=indptr, indices=indices, slots=slots)

    @classmethod
    def build_sorted(cls, n: int, groups: list[np.ndarray]) -> Pattern:
        """:meth:`build` by a global sort of every (row, column) key (the first version's method,
        kept as the reference of the tests and benchmarks: 8x slower, 3x the memory)."""
        keys = []
        for dofs in groups:
            nd = dofs.shape[1]
            rows = np.repeat(dofs, nd, axis=1).astype(np.int64)
            cols = np.tile(dofs, (1, nd)).astype(np.int64)
            keys.append((rows * n + cols).ravel())
        diag = np.arange(n, dtype=np.int64) * (n + 1)  # every dof keeps a diagonal slot
        all_keys = np.sort(np.concatenate(keys + [diag]))
        all_keys = all_keys[np.concatenate(([True], all_keys[1:] != all_keys[:-1]))]
        rows = all_keys // n
        indices = (all_keys - rows * n).astype(np.int32 if n < 2**31 else np.int64)
        indptr = np.zeros(n + 1, dtype=np.int64)
        np.cumsum(np.bincount(rows, minlength=n), out=indptr[1:])
        slots = []
        kind = np.int32 if all_keys.size < 2**31 else np.int64
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
        """Data positions (ascending) of every entry in ``rows`` or in the columns ``rows``, and of
        their diagonals."""
        mark = np.zeros(self.n, dtype=np.bool_)
        mark[np.asarray(rows, dtype=np.int64)] = True
        return _marked_positions(self.indptr, self.indices, mark)


@kernel
def scatter_matrix(data: np.ndarray, slots: np.ndarray, ke: np.ndarray) -> None:
    """data[slots] += ke for element blocks ke (n_el, nd, nd); serial, memory bound."""
    n_el, nd, _ = ke.shape
    for e in range(n_el):
        for i in range(nd):
            for j in range(nd):
                data[slots[e, i, j]] += ke[e, i, j]


@kernel
def scatter_vector(f: np.ndarray, dofs: np.ndarray, fe: np.ndarray) -> None:
    """f[dofs] += fe for element vectors fe (n_el, nd)."""
    n_el, nd = fe.shape
    for e in range(n_el):
        for i in range(nd):
            f[dofs[e, i]] += fe[e, i]


# --------------------------------------------------------------------------------------------
# row-wise pattern (Pattern.build): incidence, row lengths, rows and slots
# --------------------------------------------------------------------------------------------

ROWS_PER_CHUNK = 4096  # rows per prange item of the row passes (one small sort buffer each)


@kernel
def _incidence(n, flat, start, nd_of):
    """Per dof the (element, local index) entries that hold it, CSR-like (ptr (n+1,), el, i), and
    the widest row bound: max over dofs of 1 + the sum of the holding elements' dof counts."""
    ptr = np.zeros(n + 1, dtype=np.int64)
    width = np.ones(n, dtype=np.int64)
    for e in range(nd_of.shape[0]):
        for i in range(nd_of[e]):
            d = flat[start[e] + i]
            ptr[d + 1] += 1
            width[d] += nd_of[e]
    for d in range(n):
        ptr[d + 1] += ptr[d]
    el = np.empty(ptr[n], dtype=np.int64)
    loc = np.empty(ptr[n], dtype=np.int64)
    fill = ptr[:-1].copy()
    for e in range(nd_of.shape[0]):
        for i in range(nd_of[e]):
            d = flat[start[e] + i]
            el[fill[d]] = e
            loc[fill[d]] = i
            fill[d] += 1
    return ptr, el, loc, width.max() if n else 1


@inner
def lower_bound(values, lo, hi, x):
    """The first position p in [lo, hi] with values[p] >= x (values[lo:hi] sorted; hi if none)."""
    while lo < hi:
        mid = (lo + hi) // 2
        if values[mid] < x:
            lo = mid + 1
        else:
            hi = mid
    return lo


@inner
def _sorted_row(r, inc_ptr, inc_el, flat, start, nd_of, buf):
    """The sorted unique columns of row r in buf[:k]; returns k (insertion sort: rows are short)."""
    k = 0
    buf[0] = r
    k = 1
    for q in range(inc_ptr[r], inc_ptr[r + 1]):
        e = inc_el[q]
        for j in range(nd_of[e]):
            c = flat[start[e] + j]
            pos = k  # insert c keeping buf[:k] sorted and unique
            while pos > 0 and buf[pos - 1] > c:
                pos -= 1
            if pos > 0 and buf[pos - 1] == c:
                continue
            for m in range(k, pos, -1):
                buf[m] = buf[m - 1]
            buf[pos] = c
            k += 1
    return k


@parallel_kernel(cost=0.15e-6, items_arg=0)  # s per row, one thread
def _row_lengths(inc_ptr, inc_el, flat, start, nd_of, width):
    """Entries per row (n,)."""
    n = inc_ptr.shape[0] - 1
    out = np.empty(n, dtype=np.int64)
    m = (n + ROWS_PER_CHUNK - 1) // ROWS_PER_CHUNK
    for ch in nb.prange(m):
        buf = np.empty(width, dtype=np.int64)
        for r in range(ch * ROWS_PER_CHUNK, min(n, (ch + 1) * ROWS_PER_CHUNK)):
            out[r] = _sorted_row(r, inc_ptr, inc_el, flat, start, nd_of, buf)
    return out


@parallel_kernel(cost=0.4e-6, items_arg=0)  # s per row, one thread
def _fill_rows(inc_ptr, inc_el, inc_i, flat, start, nd_of, slot_start, width, indptr, indices, slots):
    """Column indices of every row, and the slot of every element entry (row-major per element)."""
    n = inc_ptr.shape[0] - 1
    m = (n + ROWS_PER_CHUNK - 1) // ROWS_PER_CHUNK
    for ch in nb.prange(m):
        buf = np.empty(width, dtype=np.int64)
        for r in range(ch * ROWS_PER_CHUNK, min(n, (ch + 1) * ROWS_PER_CHUNK)):
            k = _sorted_row(r, inc_ptr, inc_el, flat, start, nd_of, buf)
            a = indptr[r]
            for j in range(k):
                indices[a + j] = buf[j]
            for q in range(inc_ptr[r], inc_ptr[r + 1]):
                e, i = inc_el[q], inc_i[q]
                nd = nd_of[e]
                for j in range(nd):
                    c = flat[start[e] + j]
                    slots[slot_start[e] + i * nd + j] = a + lower_bound(buf, 0, k - 1, c)


@kernel
def _marked_positions(indptr, indices, mark):
    """(positions of the entries whose row or column is marked, positions of the marked diagonals)."""
    n = indptr.shape[0] - 1
    hits = 0
    diags = 0
    for r in range(n):
        for q in range(indptr[r], indptr[r + 1]):
            if mark[r] or mark[indices[q]]:
                hits += 1
                if mark[r] and indices[q] == r:
                    diags += 1
    hit = np.empty(hits, dtype=np.int64)
    diag = np.empty(diags, dtype=np.int64)
    h = 0
    d = 0
    for r in range(n):
        for q in range(indptr[r], indptr[r + 1]):
            if mark[r] or mark[indices[q]]:
                hit[h] = q
                h += 1
                if mark[r] and indices[q] == r:
                    diag[d] = q
                    d += 1
    return hit, diag
