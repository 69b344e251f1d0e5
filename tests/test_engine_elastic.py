"""Bulk Q4 and the engine on elastic problems: patch test, closed form with confinement."""

import numpy as np
import pytest

from rockfrac.elements.solid import ElasticQ4
from rockfrac.fem import quad4
from rockfrac.mesh import cracked_specimen
from rockfrac.model import Model
from rockfrac.solve.linear import SuperLU
from rockfrac.solve.newton import Loads, NewtonOptions, newton_step

E, NU = 1.5e7, 0.3


def distorted_patch():
    """Four quads around an off-centre interior node (no two alike)."""
    nodes = np.array([[0, 0], [1, 0], [2, 0], [0, 1], [1.3, 0.8], [2, 1], [0, 2], [1, 2], [2, 2]], float)
    quads = np.array([[0, 1, 4, 3], [1, 2, 5, 4], [3, 4, 7, 6], [4, 5, 8, 7]])
    return nodes, quads


def test_patch_test_reproduces_linear_field_exactly():
    nodes, quads = distorted_patch()
    bulk = ElasticQ4(nodes, quads, E, NU)
    boundary = np.array([0, 1, 2, 3, 5, 6, 7, 8])
    dirichlet = np.sort(np.concatenate([2 * boundary, 2 * boundary + 1]))
    model = Model(len(nodes), [bulk], dirichlet)
    a = np.array([[1e-3, 2e-4], [-3e-4, 5e-4]])  # u = a x + b
    exact = (nodes @ a.T + np.array([1e-4, -2e-4])).ravel()
    zero = np.zeros(model.n_dofs)
    loads = Loads(np.zeros(dirichlet.size), exact[dirichlet], zero, zero)
    res = newton_step(model, zero, 0.0, 1.0, loads, SuperLU(), NewtonOptions())
    assert res.converged
    np.testing.assert_allclose(res.u, exact, rtol=0, atol=1e-15)
    sig = bulk.stresses(res.u)
    eps = np.array([a[0, 0], a[1, 1], a[0, 1] + a[1, 0]])
    expected = quad4.plane_strain_elasticity(E, NU) @ eps
    np.testing.assert_allclose(sig[..., [0, 1, 3]], np.broadcast_to(expected, (4, 4, 3)), rtol=1e-11)
    np.testing.assert_allclose(sig[..., 2], NU * (expected[0] + expected[1]), rtol=1e-11)


def test_stiffness_symmetric_with_three_rigid_modes():
    nodes, quads = distorted_patch()
    ke = quad4.elastic_stiffness(np.ascontiguousarray(nodes[quads]), quad4.plane_strain_elasticity(E, NU),
                                 quad4.DN_REF)
    for k in ke:
        np.testing.assert_allclose(k, k.T, rtol=1e-12, atol=1e-6)
        w = np.linalg.eigvalsh(k)
        assert np.sum(np.abs(w) < 1e-8 * w.max()) == 3


def test_inverted_element_rejected():
    nodes, quads = distorted_patch()
    with pytest.raises(ValueError, match="inverted"):
        ElasticQ4(nodes, quads[:, ::-1], E, NU)


@pytest.mark.parametrize("n", [1, 3])
def test_uncracked_specimen_matches_closed_form_with_confinement(tmp_path, n):
    """F = W (E/(1-nu^2) u/H + nu/(1-nu) p) for plane strain under lateral pressure p."""
    from rockfrac.case.schema import parse_case
    from rockfrac.output.csvout import read_csv
    from rockfrac.run import run_case

    case = parse_case({
        "mesh": {"crack": False, "nx": n, "ny": n},
        "bulk": {"E": E, "nu": NU},
        "loading": {"confinement": 2e4, "confinement_steps": 2, "axial_displacement": 1e-3, "axial_steps": 3},
    })
    run_case(case, tmp_path)
    h = read_csv(tmp_path / "history.csv")
    W, H, p = 0.04, 0.08, 2e4
    expected = W * (E / (1 - NU**2) * h["u_axial"] / H + NU / (1 - NU) * p * h["load_factor"] ** (h["stage"] == "confinement"))
    np.testing.assert_allclose(h["F_axial"], expected, rtol=1e-10)
    assert h["u_axial"][-1] == pytest.approx(1e-3, rel=1e-12)


def test_specimen_geometry_and_groups():
    m = cracked_specimen(0.04, 0.08, np.radians(60), nx=2, ny=3)
    assert m.check() == []
    assert m.interfaces.shape == (2, 4)
    minus, plus = m.interfaces[:, :2], m.interfaces[:, 2:]
    np.testing.assert_allclose(m.nodes[minus], m.nodes[plus])
    t = m.nodes[minus[:, 1]] - m.nodes[minus[:, 0]]
    np.testing.assert_allclose(np.arctan2(t[:, 1], t[:, 0]), np.radians(60), rtol=1e-12)
    np.testing.assert_allclose(m.nodes[m.node_sets["top"], 1], 0.08)
    lengths = np.linalg.norm(np.diff(m.nodes[m.edge_sets["left"]], axis=1)[:, 0], axis=1)
    assert lengths.sum() == pytest.approx(0.08)
    with pytest.raises(ValueError, match="left and right edges"):
        cracked_specimen(0.04, 0.08, np.radians(80))
