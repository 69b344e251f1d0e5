"""A fill-reducing ordering for saddle points: each multiplier eliminated after its displacements.

An RP CSE's tangent [[A, B1], [B2, C]] (displacements first, then the multipliers) has a zero
block C while its points are constrained (eq. 33). A general-purpose ordering of the whole pattern
may eliminate a multiplier before the displacements it couples: its pivot is then zero, and a
static-pivoting solver (PARDISO) perturbs it and leaves residuals of 1e-3 to 1e4 on surfaces on
every edge. Here the displacements are ordered by nested dissection (METIS) on the pattern of
A + B1 B2 (its transpose added: the fill a multiplier's elimination brings among its displacements),
and every multiplier comes right after the last of its displacements in that order: by then its
Schur complement -B2 A_S^-1 B1 (A_S the eliminated displacements' block, positive definite with
the bulk and the augmentation) is a nonzero pivot wherever the constraints are independent, so
pivots need no perturbing. The price is fill: multipliers on a separator's displacements come late
(on the grains' RP edge points the refactorization took 2.7 times that in PARDISO's own order;
benchmarks/README.md, "PARDISO without matching").
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp


def _structure(m: sp.spmatrix) -> sp.csr_matrix:
    """m's stored entries (explicit zeros included: a run's pattern is fixed) as ones."""
    m = sp.csr_matrix(m)
    return sp.csr_matrix((np.ones(m.nnz), m.indices, m.indptr), shape=m.shape)


def saddle_order(a: sp.csr_matrix, n_u: int) -> np.ndarray:
    """The rows of ``a`` (n_u displacement rows first, then the multipliers) in elimination order,
    first eliminated first: nested dissection of the displacements' graph with the multipliers'
    couplings folded in, each multiplier placed after its last displacement (in index order where
    several share it); a multiplier coupling no displacement comes last."""
    import pymetis

    a = sp.csr_matrix(a)
    n = a.shape[0]
    if not 0 < n_u < n:
        raise ValueError(f"saddle_order: n_u = {n_u} must split the {n} rows into displacements and multipliers")
    b1 = _structure(a[:n_u, n_u:])
    b2 = _structure(a[n_u:, :n_u])
    graph = _structure(a[:n_u, :n_u]) + b1 @ b2
    graph = (graph + graph.T).tocsr()
    graph.setdiag(0)
    graph.eliminate_zeros()
    _, positions = pymetis.nested_dissection(pymetis.CSRAdjacency(graph.indptr, graph.indices))
    position_u = np.asarray(positions, dtype=np.int64)  # each displacement's place in their order
    coupled = (b2 + b1.T).tocsr()  # each multiplier's displacements, either way round
    count = np.diff(coupled.indptr)
    last = np.full(n - n_u, n_u, dtype=np.int64)
    rows = np.flatnonzero(count)
    if rows.size:
        last[rows] = np.maximum.reduceat(position_u[coupled.indices], coupled.indptr[rows])
    key = np.concatenate([2 * position_u, 2 * last + 1])  # a multiplier just after its last displacement
    return np.argsort(key, kind="stable")
