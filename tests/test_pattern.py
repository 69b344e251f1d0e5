"""The row-wise CSR pattern (fem.assembly.Pattern.build) equals the global-sort one (build_sorted)
in every array: indptr, indices and the slot maps of every group, on the models of real cases
(every cell type, cohesive EP and RP groups with multiplier dofs, embedded cells, Gmsh meshes with
several regions, 3D hexahedra), and the Dirichlet bookkeeping equals its NumPy definition."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rockfrac.case.build import build
from rockfrac.case.schema import load_case, parse_case
from rockfrac.fem.assembly import Pattern
from rockfrac.studies import table1

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ["examples/band/band.toml", "examples/grains/grains.toml", "examples/paper/ede.toml",
            "examples/rock_tests/brazilian/everywhere.toml", "examples/rock_tests/borehole/breakout.toml",
            "examples/rock_tests/bending/notched_beam.toml", "examples/rock_tests/direct_shear/joint.toml"]


def same(a: Pattern, b: Pattern) -> None:
    assert a.n == b.n and np.array_equal(a.indptr, b.indptr) and a.indptr.dtype == b.indptr.dtype
    assert np.array_equal(a.indices, b.indices) and a.indices.dtype == b.indices.dtype
    assert len(a.slots) == len(b.slots)
    for x, y in zip(a.slots, b.slots):
        assert x.shape == y.shape and x.dtype == y.dtype and np.array_equal(x, y)


def check_model(model) -> None:
    groups = [g.dofs for g in model.groups]
    reference = Pattern.build_sorted(model.n_dofs, groups)
    same(Pattern.build(model.n_dofs, groups), reference)
    # the model's own: the same arrays, its constant groups' slot maps dropped after assembly
    assert np.array_equal(model.pattern.indptr, reference.indptr)
    assert np.array_equal(model.pattern.indices, reference.indices)
    for g, mine, ref in zip(model.groups, model.pattern.slots, reference.slots):
        assert mine.size == 0 if g.constant else np.array_equal(mine, ref)
    # Dirichlet positions against their definition
    p = model.pattern
    row_of = np.repeat(np.arange(p.n), np.diff(p.indptr))
    mark = np.zeros(p.n, dtype=bool)
    mark[model.dirichlet] = True
    hit, diag = p.positions(model.dirichlet)
    assert np.array_equal(hit, np.flatnonzero(mark[row_of] | mark[p.indices]))
    assert np.array_equal(diag, np.flatnonzero(mark[row_of] & (row_of == p.indices)))
    assert np.array_equal(model.free, np.setdiff1d(np.arange(model.n_dofs), model.dirichlet))


@pytest.mark.parametrize("path", EXAMPLES)
def test_examples_pattern_equals_the_sorted_one(path):
    built = build(load_case(ROOT / path))
    kinds = {type(g).__name__ for g in built.model.groups}
    assert kinds
    check_model(built.model)


@pytest.mark.parametrize("form", ["ep", "rp"])
def test_paper_cse_pattern_equals_the_sorted_one(form):
    case = table1.cse_case(form, 1e9 if form == "ep" else None, axial_steps=4)
    case["mesh"].update(nx=3, ny=5)
    built = build(parse_case(case, "t.toml"))
    if form == "rp":
        assert built.model.n_dofs > 2 * built.model.n_nodes  # multiplier dofs in the pattern
    check_model(built.model)


def test_random_groups_with_repeats_empty_groups_and_untouched_dofs():
    rng = np.random.default_rng(5)
    n = 700
    groups = [rng.integers(0, n - 50, (400, 8)), rng.integers(0, n - 50, (60, 6)), np.zeros((0, 4), dtype=np.int64),
              rng.integers(0, n - 50, (30, 1))]
    groups[0][:10, 3] = groups[0][:10, 5]  # a dof twice in one element
    a = Pattern.build(n, groups)
    same(a, Pattern.build_sorted(n, groups))
    assert np.all(np.diff(a.indptr)[n - 50:] == 1)  # untouched dofs keep their diagonal only
    with pytest.raises(ValueError, match="outside"):
        Pattern.build(10, [np.array([[0, 10]])])


def test_a_hex_box_pattern_equals_the_sorted_one():
    nx, ny, nz = 3, 4, 5
    ids = np.arange((nx + 1) * (ny + 1) * (nz + 1)).reshape(nz + 1, ny + 1, nx + 1)
    c = ids[:-1, :-1, :-1]
    cells = np.stack([c, c + 1, c + nx + 2, c + nx + 1, *(v + (nx + 1) * (ny + 1) for v in (c, c + 1, c + nx + 2,
                                                                                          c + nx + 1))], -1)
    cells = cells.reshape(-1, 8)
    dofs = (3 * cells[:, :, None] + np.arange(3)).reshape(cells.shape[0], -1)
    n = 3 * ids.size
    a = Pattern.build(n, [dofs])
    same(a, Pattern.build_sorted(n, [dofs]))
    assert np.diff(a.indptr).max() == 81  # an inner node: 27 nodes x 3 dofs
