"""The saddle-point ordering (rockfrac.solve.ordering): every multiplier eliminated after the
displacements it couples, so an LU without pivoting meets no zero pivot, and PARDISO without its
matching perturbs none on the paper's RP saddle points (benchmarks/README.md, "PARDISO without
matching")."""

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from test_linear_solvers import rp_case, tangents

from rockfrac.case.build import build
from rockfrac.case.schema import parse_case
from rockfrac.solve import linear
from rockfrac.solve.fallback import Checked, relative_residual
from rockfrac.solve.ordering import saddle_order

needs_pardiso = pytest.mark.skipif("pardiso" not in linear.available(), reason="PARDISO (pypardiso) not installed")


def tied_grid(n: int, seed: int) -> tuple[sp.csr_matrix, int]:
    """Two n x n grid Laplacians (shifted: positive definite) whose facing edge nodes are tied by
    multipliers, [[A, B^T], [B, 0]] with B = [+1 on one side, -1 on the other] per tie, plus random
    symmetric couplings scaled small; and the number of displacement rows."""
    rng = np.random.default_rng(seed)
    lap = sp.diags([-1.0, 2.2, -1.0], [-1, 0, 1], shape=(n, n))
    block = sp.kron(lap, sp.eye(n)) + sp.kron(sp.eye(n), lap)
    a = sp.block_diag([block, block]).tocsr()
    a = a + 0.01 * sp.diags(rng.uniform(size=a.shape[0]))
    n_u = a.shape[0]
    right = np.arange(n) * n + (n - 1)  # the first grid's right edge
    left = n * n + np.arange(n) * n  # the second grid's left edge
    b = sp.csr_matrix((np.r_[np.ones(n), -np.ones(n)], (np.r_[np.arange(n), np.arange(n)], np.r_[right, left])),
                      shape=(n, n_u))
    return sp.bmat([[a, b.T], [b, None]], format="csr"), n_u


def test_each_multiplier_comes_after_its_displacements_and_nothing_is_lost():
    a, n_u = tied_grid(12, 0)
    order = saddle_order(a, n_u)
    assert np.array_equal(np.sort(order), np.arange(a.shape[0]))  # a permutation
    position = np.empty_like(order)
    position[order] = np.arange(order.size)
    b = a[n_u:, :n_u].tocsr()
    for j in range(b.shape[0]):
        assert position[n_u + j] > position[b.indices[b.indptr[j]:b.indptr[j + 1]]].max()
    # not simply "multipliers last": they are spread through the order
    assert position[n_u:].min() < n_u


def pivots_without_exchanges(a: np.ndarray) -> np.ndarray:
    """The pivots of Gaussian elimination of a dense matrix in its own order, no row exchanges (a
    zero pivot stops the elimination: the rest are returned as zeros)."""
    a = a.astype(float).copy()
    out = np.zeros(a.shape[0])
    for k in range(a.shape[0]):
        out[k] = a[k, k]
        if out[k] == 0.0:
            break
        a[k + 1:, k + 1:] -= np.outer(a[k + 1:, k] / a[k, k], a[k, k + 1:])
    return out


def test_elimination_without_exchanges_in_this_order_meets_no_zero_pivot_where_a_general_one_does():
    """Gaussian elimination with no row exchanges (what a static-pivoting solver attempts before it
    perturbs) of the tied grids: in the saddle order every pivot is well away from zero and the
    solution is exact to round-off; with the multipliers first, or in nested dissection of the whole
    pattern, a multiplier meets a zero pivot."""
    a, n_u = tied_grid(6, 1)
    dense = a.toarray()
    order = saddle_order(a, n_u)
    pivots = pivots_without_exchanges(dense[np.ix_(order, order)])
    assert np.abs(pivots).min() > 1e-3 * np.abs(pivots).max()
    first = np.r_[np.arange(n_u, a.shape[0]), np.arange(n_u)]
    assert pivots_without_exchanges(dense[np.ix_(first, first)])[0] == 0.0
    import pymetis

    graph = sp.csr_matrix(abs(a) + abs(a.T))
    graph.setdiag(0)
    graph.eliminate_zeros()
    whole, _ = pymetis.nested_dissection(pymetis.CSRAdjacency(graph.indptr, graph.indices))
    assert (np.abs(pivots_without_exchanges(dense[np.ix_(whole, whole)])) < 1e-12).any()
    rhs = np.random.default_rng(2).standard_normal(a.shape[0])
    p = a[order][:, order].tocsc()
    lu = spla.splu(p, permc_spec="NATURAL", diag_pivot_thresh=0.0, options={"SymmetricMode": True})
    x = np.empty_like(rhs)
    x[order] = lu.solve(rhs[order])
    assert relative_residual(a, x, rhs) < 1e-12


def test_a_split_that_is_not_a_saddle_point_is_refused():
    a, n_u = tied_grid(4, 3)
    for bad in (0, a.shape[0]):
        with pytest.raises(ValueError, match="must split"):
            saddle_order(a, bad)
    with pytest.raises(ValueError, match="matching=False"):
        linear.Pardiso(multipliers_from=n_u)


@pytest.fixture(scope="module")
def paper_saddles():
    """The paper's RP specimen on 16 x 16 quads: its tangent with the CSE rigid (zero diagonals on the
    multiplier rows) and one with it yielding, and its number of displacement dofs."""
    d = rp_case(16)
    n_u = build(parse_case(d, "t.toml")).model.n_u
    mats = tangents(d, 41)
    return {"rigid": mats[20], "plastic": mats[40]}, n_u


@needs_pardiso
@pytest.mark.parametrize("state", ["rigid", "plastic"])
def test_pardiso_in_the_saddle_order_perturbs_no_pivot_where_its_own_order_does(paper_saddles, state):
    """PARDISO without matching on the paper's RP saddle point: in its own (METIS) order it perturbs
    pivots of the rigid one (iparm(14)); in the saddle order (iparm(5) = 1) none of either, and its
    solution is SuperLU's."""
    mats, n_u = paper_saddles
    a = mats[state]
    b = np.random.default_rng(4).standard_normal(a.shape[0])
    own, saddle = linear.Pardiso(matching=False), linear.Pardiso(matching=False, multipliers_from=n_u)
    own.factorize(a).solve(b)
    x = saddle.factorize(a).solve(b)
    assert saddle._solver.iparm[4] == 1 and saddle.name == "pardiso without matching, saddle ordering"
    assert saddle._solver.iparm[13] == 0 and (own._solver.iparm[13] > 0 or state == "plastic")
    assert relative_residual(a, x, b) < 1e-12
    exact = spla.splu(a.tocsc()).solve(b)
    assert np.abs(x - exact).max() <= 1e-9 * np.abs(exact).max()
    # a matrix without multipliers (the split beyond its rows) is analysed in PARDISO's own order
    block = a[:n_u, :n_u].tocsr() + sp.eye(n_u, format="csr")
    saddle.factorize(block)
    assert saddle._solver.iparm[4] == 0


@needs_pardiso
def test_auto_orders_pardiso_without_matching_as_a_saddle_where_the_tangent_has_multipliers():
    nodes = np.random.default_rng(5).uniform(size=(50, 2))
    with_multipliers = linear.make_solver("auto", nodes, nodes.size + 30)
    inner = with_multipliers.then
    assert isinstance(inner, Checked) and inner.first.multipliers_from == nodes.size
    assert inner.first.name == "pardiso without matching, saddle ordering"
    for plain in (linear.make_solver("auto", nodes, nodes.size), linear.make_solver("auto"),
                  linear.make_solver("auto", nodes, nodes.size + 30, enrichment=True)):
        assert plain.then.first.multipliers_from is None and plain.then.first.name == "pardiso without matching"
