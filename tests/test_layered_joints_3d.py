"""A 3D stack of layers with cohesive joints on every internal horizontal plane (rock_tests.box with
layers, [cohesive] where = 'boundaries'), under a pressure on the top, on rollers: uniaxial
stress sigma_zz = -p in every layer, so the top settles by p L / E plus p / kn per EP joint, and an
unyielded RP stack is the unsplit elastic box exactly. The problem of benchmarks/scaling_3d.py
--problem joints, at its smallest."""

from __future__ import annotations

import numpy as np
import pytest

from rockfrac.api import make_case, run
from rockfrac.mesh import rock_tests as rt
from rockfrac.mesh.gmsh_io import read_mesh

E, NU, P, KN = 2e10, 0.25, 1e6, 1e11
LAW = {"GfI": 50.0, "GfII": 500.0, "chi_p": 1e6, "chi_r": 0.0, "c_p": 2e6, "c_r": 0.0, "phi_p": 0.6,
       "phi_r": 0.5, "psi_p": 0.1, "alpha_chi": 5.0, "alpha_c": 5.0, "alpha_phi": 5.0, "alpha_psi": 5.0}
ROLLERS = {"left": {"x": 0.0}, "front": {"y": 0.0}, "bottom": {"z": 0.0}}


def test_layered_box_alternates_regions_and_conforms(tmp_path):
    for element, per_cell in (("hex8", 1), ("tet4", 6)):
        m = read_mesh(rt.box(tmp_path / f"{element}.msh", (1.0, 1.0, 2.0), (2, 3, 4), element=element,
                             layers=4), dim=3)
        assert m.check() == [] and m.n_nodes == 3 * 4 * 5  # conforming: the layers share their nodes
        labels = {name: m.cells[idx] for name, idx in m.regions.items()}
        assert set(labels) == {"even", "odd"}
        for name, first in (("even", 0), ("odd", 1)):
            z = m.nodes[labels[name]][:, :, 2].mean(axis=1)
            assert len(z) == 2 * 2 * 3 * per_cell
            layer = np.floor(z / 0.5).astype(int)
            assert set(layer) == {first, first + 2}
    m = read_mesh(rt.box(tmp_path / "two.msh", (1.0, 1.0, 2.0), (2, 3, 4), layers=2), dim=3)
    assert m.n_nodes == 3 * 4 * 5 and {k: len(v) for k, v in m.regions.items()} == {"even": 12, "odd": 12}
    assert m.nodes[m.cells[m.regions["odd"]]][:, :, 2].min() == pytest.approx(1.0)
    with pytest.raises(ValueError, match="layers must be a whole number >= 1 dividing divisions"):
        rt.box(tmp_path / "bad.msh", (1.0, 1.0, 2.0), (2, 3, 4), layers=3)


@pytest.mark.parametrize("element", ["hex8", "tet4"])
@pytest.mark.parametrize("form", ["ep", "rp"])
def test_joints_of_a_pressed_stack_settle_by_p_over_kn(tmp_path, element, form):
    layers, height = 4, 2.0
    box = rt.box(tmp_path / "b.msh", (1.0, 1.0, height), (2, 2, layers), element=element, layers=layers)
    law = dict(LAW, **({"kn": KN, "kt": KN} if form == "ep" else {}))
    case = make_case(mesh={"kind": "gmsh", "file": str(box)}, bulk={"E": E, "nu": NU},
                     cohesive={"where": "boundaries", "form": form, **law},
                     stages=[{"name": "press", "displacement": ROLLERS, "pressure": {"top": P}}],
                     output={"picture": False})
    r = run(case, tmp_path / "o")
    assert r.completed
    mesh = r.built.mesh
    # one interface per internal horizontal face (two triangles per square in tetrahedra)
    assert len(mesh.interfaces) == (layers - 1) * 2 * 2 * (1 if element == "hex8" else 2)
    assert mesh.interfaces.shape[1] == (8 if element == "hex8" else 6)
    u = r.displacement()
    z = mesh.nodes[:, 2]
    cell_z = mesh.nodes[mesh.cells][:, :, 2].mean(axis=1)
    # each node's layer: from a cell holding it (the copies on a joint belong to one side)
    layer = np.full(mesh.n_nodes, -1)
    layer[mesh.cells.ravel()] = np.repeat(np.floor(cell_z / (height / layers)).astype(int), mesh.cells.shape[1])
    assert layer.min() == 0
    joints_below = layer if form == "ep" else np.zeros_like(layer)
    exact_z = -P * z / E - joints_below * P / KN
    scale = P * height / E
    assert np.abs(u[:, 2] - exact_z).max() < 1e-9 * scale
    np.testing.assert_allclose(u[:, 0], NU * P * mesh.nodes[:, 0] / E, atol=1e-9 * scale)
    np.testing.assert_allclose(u[:, 1], NU * P * mesh.nodes[:, 1] / E, atol=1e-9 * scale)


def test_sliding_rp_joints_solved_by_gmres_amg_match_the_direct_solve(tmp_path):
    """The saddle-point tangents of RP joints (multiplier rows, constrained and sliding) solved by
    GMRES with the block-triangular AMG preconditioner give the direct solver's history: the stack
    under a pressure, then its top dragged sideways until the joints slide."""
    box = rt.box(tmp_path / "b.msh", (1.0, 1.0, 1.0), (2, 2, 4), element="tet4", layers=2)
    histories = {}
    for linear in ("superlu", "gmres-amg"):
        case = make_case(mesh={"kind": "gmsh", "file": str(box)}, bulk={"E": E, "nu": NU},
                         cohesive={"where": "boundaries", "form": "rp", "augmentation": 1e12, **LAW},
                         stages=[{"name": "press", "displacement": {"bottom": {"x": 0.0, "y": 0.0, "z": 0.0}},
                                  "pressure": {"top": P}},
                                 {"name": "drag", "steps": 6, "pressure": {"top": P},
                                  "displacement": {"bottom": {"x": 0.0, "y": 0.0, "z": 0.0},
                                                   "top": {"x": 1.75e-4, "y": 0.0}}}],
                         solver={"linear": linear}, output={"picture": False})
        r = run(case, tmp_path / linear)
        assert r.completed, r.message
        histories[linear] = r.history
    direct, krylov = histories["superlu"], histories["gmres-amg"]
    assert direct["n_plastic"][-1] > 0  # the joint slides
    # the same Newton iterations, but for one where a step ends at round-off: an elastic drag step
    # whose first correction lands within the tolerance (SuperLU: residual 2e-15, on 2026-11-28's
    # fresh installs) or just above it (GMRES: 7e-14), then takes one more
    off = np.abs(direct["newton_iterations"] - krylov["newton_iterations"])
    assert off.max() <= 1 and np.count_nonzero(off) <= 1, (direct["newton_iterations"], krylov["newton_iterations"])
    for q in ("R_top_x", "u_top_z"):
        np.testing.assert_allclose(krylov[q], direct[q], rtol=0, atol=1e-8 * np.abs(direct[q]).max())
