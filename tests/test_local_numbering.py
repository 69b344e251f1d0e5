"""An MPI rank's local numbering (issue 17): its groups renumbered from the global dofs give the same
element vectors and blocks on the same values, whatever the numbering. Checked on one process with a
shuffled numbering of every dof, for every kind of group: bulk solids, EP and RP cohesive points
(their jumps, path measure and redundant multipliers), nodal embedded cracks (cut cells and the
held enrichments, whose dofs the registry makes as cells are cut)."""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest

from rockfrac.case.build import build
from rockfrac.case.schema import parse_case
from rockfrac.elements.cse_groups import CohesiveRP
from rockfrac.fem.dofs import LocalNumbering

ROOT = Path(__file__).resolve().parent.parent


def test_local_numbers_and_back():
    numbering = LocalNumbering(np.array([7, 2, 9, 4]))
    np.testing.assert_array_equal(numbering.local(np.array([[9, 7], [4, 2]])), [[2, 0], [3, 1]])
    np.testing.assert_array_equal(numbering.global_(np.array([3, 0])), [4, 7])
    local, held = numbering.local_part(np.array([2, 5, 4, 11, 0]))
    np.testing.assert_array_equal(local, [1, 3])
    np.testing.assert_array_equal(held, [True, False, True, False, False])
    with pytest.raises(ValueError, match=r"global dofs \[5, 11\] are not among this rank's 4 local dofs"):
        numbering.local(np.array([2, 5, 11]))


def _case(name: str, **embedded) -> dict:
    case = tomllib.loads((ROOT / "examples" / name).read_text())
    if embedded:
        case["embedded"].update(embedded)
    return case


CASES = {
    "rp": lambda: _case("paper/cse_rp.toml"),
    "ep": lambda: _case("paper/cse_ep_k1e9.toml"),
    "nodal": lambda: _case("joint/joint.toml", kinematics="nodal", kn=1e10, kt=1e10, tracking="local"),
}


@pytest.mark.parametrize("name", sorted(CASES))
def test_groups_renumbered_evaluate_alike(name):
    built = build(parse_case(CASES[name](), name))
    model = built.model
    n = model.n_dofs
    rng = np.random.default_rng(3)
    u = 1e-6 * rng.standard_normal(n)
    u_n = 0.3 * u
    held_pairs = [g.jump_dofs[:3].ravel() for g in built.cohesives]  # both sides of some points held
    dirichlet = np.unique(np.concatenate([rng.choice(model.n_u, size=n // 10, replace=False), *held_pairs]))
    model.begin_step()
    before = [(g.evaluate(u, u_n), g.dofs.copy(), np.sort(g.redundant_extras(dirichlet))) for g in model.groups
              if not g.constant]
    groups = [g for g in model.groups if not g.constant]
    assert any(g.dofs.shape[0] for g in groups)
    measures = [(g, m(u)) for g in groups if (m := g.path_measure(n)) is not None]
    assert len(measures) >= 1
    if name == "nodal":  # cut cells and enrichments there to renumber
        assert sum(g.dofs.shape[0] for g in groups if "cut cells" in g.name) > 0
        assert any(r.size for _, _, r in before)  # the held q's of prescribed nodes
    if name == "rp":
        assert any(isinstance(g, CohesiveRP) and r.size for g, (_, _, r) in zip(groups, before))
    perm = rng.permutation(n)  # local dof k is global dof perm[k]
    numbering = LocalNumbering(perm)
    for g in model.groups:
        g.renumber(numbering)
    u_local, u_n_local = u[perm], u_n[perm]
    model.begin_step()
    for g, (ev, dofs, redundant) in zip(groups, before):
        again = g.evaluate(u_local, u_n_local)
        np.testing.assert_array_equal(perm[g.dofs], dofs)
        np.testing.assert_array_equal(again.fe, ev.fe)
        np.testing.assert_array_equal(again.ke, ev.ke)
        local_redundant = g.redundant_extras(numbering.local(dirichlet))
        np.testing.assert_array_equal(np.sort(perm[local_redundant]), redundant)
    for g, (value, grad) in measures:
        value_local, grad_local = g.path_measure(n)(u_local)
        assert value_local == pytest.approx(value, rel=1e-14)  # summed in another order
        np.testing.assert_array_equal(grad_local, grad[perm])
