"""The partition of a split mesh for MPI runs (rockfrac.mesh.partition): METIS on the element graph
with the cohesive elements in it, node owners, and the dof numbering by contiguous blocks."""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest

from rockfrac.case.build import build
from rockfrac.case.schema import parse_case
from rockfrac.mesh.partition import element_graph, partition

BRAZILIAN = Path(__file__).resolve().parents[1] / "examples" / "rock_tests" / "brazilian"


@pytest.fixture(scope="module")
def everywhere_mesh():
    """The Brazilian disc split along every edge (coarse mesh): 236 cells, every internal edge an
    interface cell."""
    case = tomllib.loads((BRAZILIAN / "everywhere.toml").read_text())
    case["mesh"]["file"] = str(BRAZILIAN / "disc_coarse.msh")
    return build(parse_case(case, "everywhere")).mesh


@pytest.mark.parametrize("n", [2, 3, 4])
def test_every_element_and_node_owned_once_by_a_part_whose_cells_touch_it(everywhere_mesh, n):
    mesh = everywhere_mesh
    p = partition(mesh, n)
    assert p.cell_part.shape == (mesh.cells.shape[0],) and p.interface_part.shape == (mesh.interfaces.shape[0],)
    elements = np.concatenate([p.cell_part, p.interface_part])
    assert elements.min() == 0 and elements.max() == n - 1
    counts = np.bincount(elements, minlength=n)
    assert counts.max() <= 1.1 * counts.min()  # METIS balances the element counts
    # a node's owner is the lowest part among the bulk cells around it
    lowest = np.full(mesh.n_nodes, n)
    for k in range(mesh.cells.shape[1]):
        np.minimum.at(lowest, mesh.cells[:, k], p.cell_part)
    np.testing.assert_array_equal(p.node_part, lowest)


@pytest.mark.parametrize("n", [1, 2, 3])
def test_the_dofs_are_renumbered_in_one_contiguous_block_per_part(everywhere_mesh, n):
    mesh = everywhere_mesh
    p = partition(mesh, n)
    new = p.new_dofs()
    np.testing.assert_array_equal(np.sort(new), np.arange(2 * mesh.n_nodes))  # a permutation
    owned = np.concatenate([p.owned_dofs(r) for r in range(n)])
    np.testing.assert_array_equal(new[owned], np.arange(2 * mesh.n_nodes))  # blocks in order, each once
    for r in range(n):
        lo, hi = p.owned_range(r)
        assert np.all(p.node_part[p.owned_dofs(r) // 2] == r) and hi - lo == p.owned_dofs(r).shape[0]
    if n == 1:
        np.testing.assert_array_equal(new, np.arange(2 * mesh.n_nodes))  # serial numbering unchanged
    with_extras = p.with_extras(np.arange(7) % n)  # blocks of extra dofs owned round the parts
    whole_new = with_extras.new_dofs()
    for r in range(n):  # a rank's piece (its cells, their nodes): the whole numbering, nothing whole-sized
        cells = np.flatnonzero(p.cell_part == r)
        interfaces = np.flatnonzero(p.interface_part == r)
        nodes = np.unique(np.concatenate([mesh.cells[cells].ravel(), mesh.interfaces[interfaces].ravel()]))
        piece = with_extras.of_piece(r, cells, interfaces, nodes)
        starts, owned_r, petsc_of = piece.numbering()
        np.testing.assert_array_equal(owned_r, with_extras.owned_dofs(r))
        np.testing.assert_array_equal(starts, [with_extras.owned_range(q)[0] for q in range(n)] + [with_extras.n_dofs])
        touched = np.concatenate([(2 * nodes[:, None] + np.arange(2)).ravel(), 2 * mesh.n_nodes + np.arange(14)])
        np.testing.assert_array_equal(petsc_of(touched), whole_new[touched])
        # known by their counts and the rank's own only (rigid-plastic multipliers on a piece): alike
        extra_owner = np.arange(7) % n
        own = np.flatnonzero(extra_owner == r)
        counted = p.of_piece(r, cells, interfaces, nodes).with_own_extras(np.bincount(extra_owner, minlength=n), own)
        starts_c, owned_c, petsc_c = counted.numbering()
        np.testing.assert_array_equal(starts_c, starts)
        np.testing.assert_array_equal(owned_c, owned_r)
        mine = np.concatenate([(2 * nodes[:, None] + np.arange(2)).ravel(),
                               (2 * (mesh.n_nodes + own)[:, None] + np.arange(2)).ravel()])
        np.testing.assert_array_equal(petsc_c(mine), whole_new[mine])
        if n > 1:
            with pytest.raises(ValueError, match="extra dofs another rank owns"):
                petsc_c(np.array([2 * (mesh.n_nodes + int(np.flatnonzero(extra_owner != r)[0]))]))
        outside = np.setdiff1d(np.arange(mesh.n_nodes), nodes)
        if outside.size:
            with pytest.raises(ValueError, match="outside this rank's piece"):
                petsc_of(2 * outside[:1])


def test_an_interface_cell_ties_the_cells_on_both_its_sides(everywhere_mesh):
    mesh = everywhere_mesh
    graph = element_graph(mesh)
    n_cells = mesh.cells.shape[0]
    k = 7
    minus, plus = mesh.interfaces[k, :2], mesh.interfaces[k, 2:]
    neighbours = set(graph.indices[graph.indptr[n_cells + k]:graph.indptr[n_cells + k + 1]])
    for side in (minus, plus):
        cells_of_side = {c for c in range(n_cells) if np.isin(mesh.cells[c], side).any()}
        assert cells_of_side and cells_of_side <= neighbours


def test_bad_part_counts_are_refused(everywhere_mesh):
    with pytest.raises(ValueError, match="at least one part"):
        partition(everywhere_mesh, 0)
    with pytest.raises(ValueError, match="each part needs at least one element"):
        partition(everywhere_mesh, 10**6)
