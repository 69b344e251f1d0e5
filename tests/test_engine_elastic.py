"""Bulk solids and the engine on elastic problems: patch tests (Q4, Hex8), Hex8 in plane strain
against Q4, closed form of the specimen with confinement."""

import numpy as np
import pytest

from rockfrac.elements.solid import ElasticSolid
from rockfrac.fem.loads import face_pressure
from rockfrac.fem.kinematics import elastic_blocks, element_gradients
from rockfrac.fem.reference import HEX8, QUAD4
from rockfrac.laws.elastic import isotropic_elasticity, plane_strain_elasticity
from rockfrac.mesh import cracked_specimen, hex_specimen
from rockfrac.model import Model
from rockfrac.solve.linear import SuperLU
from rockfrac.solve.newton import Loads, NewtonOptions, newton_step

E, NU = 1.5e7, 0.3


def distorted_patch():
    """Four quads around an off-centre interior node (no two alike)."""
    nodes = np.array([[0, 0], [1, 0], [2, 0], [0, 1], [1.3, 0.8], [2, 1], [0, 2], [1, 2], [2, 2]], float)
    quads = np.array([[0, 1, 4, 3], [1, 2, 5, 4], [3, 4, 7, 6], [4, 5, 8, 7]])
    return nodes, quads


def distorted_hex_patch():
    """2 x 2 x 2 hexahedra with the centre node and a few others moved (no two cells alike)."""
    m = hex_specimen(2.0, 2.0, 2.0, 2, 2, 2)
    nodes = m.nodes.copy()
    centre = np.flatnonzero(np.all(np.isclose(nodes, 1.0), axis=1))
    nodes[centre] += [0.3, -0.2, 0.15]
    interior_faces = np.flatnonzero((np.isclose(nodes, 1.0).sum(axis=1) == 2) & (nodes.min(axis=1) > 0))
    nodes[interior_faces[:2]] += [0.1, 0.05, -0.1]
    boundary = np.flatnonzero(np.any(np.isclose(m.nodes, 0.0) | np.isclose(m.nodes, 2.0), axis=1))
    return nodes, m.cells, boundary


def solve_linear_field(nodes, cells, ref, boundary, grad_u):
    """Prescribe u = grad_u x + c on the boundary nodes, solve, return (u, bulk)."""
    dim = ref.dim
    bulk = ElasticSolid(nodes, cells, ref, E, NU)
    dirichlet = np.sort((dim * boundary[:, None] + np.arange(dim)).ravel())
    model = Model(len(nodes), [bulk], dirichlet, dim=dim)
    exact = (nodes @ grad_u.T + 1e-4 * np.arange(1, dim + 1)).ravel()
    zero = np.zeros(model.n_dofs)
    loads = Loads(np.zeros(dirichlet.size), exact[dirichlet], zero, zero)
    res = newton_step(model, zero, 0.0, 1.0, loads, SuperLU(), NewtonOptions())
    assert res.converged
    return res.u, exact, bulk


def test_q4_patch_test_reproduces_linear_field_exactly():
    nodes, quads = distorted_patch()
    a = np.array([[1e-3, 2e-4], [-3e-4, 5e-4]])
    u, exact, bulk = solve_linear_field(nodes, quads, QUAD4, np.array([0, 1, 2, 3, 5, 6, 7, 8]), a)
    np.testing.assert_allclose(u, exact, rtol=0, atol=1e-15)
    sig = bulk.stresses(u)
    eps = np.array([a[0, 0], a[1, 1], 0.0, a[0, 1] + a[1, 0], 0.0, 0.0])
    expected = isotropic_elasticity(E, NU) @ eps  # plane strain: sigma_zz = nu (sigma_xx + sigma_yy)
    np.testing.assert_allclose(sig, np.broadcast_to(expected, (4, 4, 6)), rtol=1e-11, atol=1e-6)
    assert expected[2] == pytest.approx(NU * (expected[0] + expected[1]))


def test_hex8_patch_test_reproduces_linear_field_exactly():
    nodes, cells, boundary = distorted_hex_patch()
    a = np.array([[1e-3, 2e-4, -1e-4], [-3e-4, 5e-4, 2e-4], [1e-4, -2e-4, -4e-4]])
    u, exact, bulk = solve_linear_field(nodes, cells, HEX8, boundary, a)
    np.testing.assert_allclose(u, exact, rtol=0, atol=1e-15)
    eps = np.array([a[0, 0], a[1, 1], a[2, 2], a[0, 1] + a[1, 0], a[1, 2] + a[2, 1], a[0, 2] + a[2, 0]])
    np.testing.assert_allclose(bulk.stresses(u), np.broadcast_to(isotropic_elasticity(E, NU) @ eps, (8, 8, 6)),
                               rtol=1e-10, atol=1e-6)


@pytest.mark.parametrize("ref,d,n_rigid", [(QUAD4, plane_strain_elasticity(E, NU), 3),
                                            (HEX8, isotropic_elasticity(E, NU), 6)])
def test_stiffness_symmetric_with_rigid_modes(ref, d, n_rigid):
    if ref is QUAD4:
        nodes, cells = distorted_patch()
    else:
        nodes, cells, _ = distorted_hex_patch()
    grads, wdet = element_gradients(nodes[cells], ref)
    assert np.all(wdet > 0)
    for k in elastic_blocks(grads, wdet, d):
        np.testing.assert_allclose(k, k.T, rtol=1e-12, atol=1e-6)
        w = np.linalg.eigvalsh(k)
        assert np.sum(np.abs(w) < 1e-8 * w.max()) == n_rigid


def test_inverted_element_rejected():
    nodes, quads = distorted_patch()
    with pytest.raises(ValueError, match="inverted"):
        ElasticSolid(nodes, quads[:, ::-1], QUAD4, E, NU)
    m = hex_specimen()
    with pytest.raises(ValueError, match="inverted"):
        ElasticSolid(m.nodes, m.cells[:, [4, 5, 6, 7, 0, 1, 2, 3]], HEX8, E, NU)


def test_hex8_in_plane_strain_matches_q4():
    """One Hex8 with u_z = 0 everywhere against the same Q4 block: equal in-plane stiffness and stress."""
    m3 = hex_specimen(0.04, 0.08, 0.05)
    k3 = ElasticSolid(m3.nodes, m3.cells, HEX8, E, NU).ke[0]
    q = np.array([[0.0, 0.0], [0.04, 0.0], [0.04, 0.08], [0.0, 0.08]])
    k2 = ElasticSolid(q, np.array([[0, 1, 2, 3]]), QUAD4, E, NU).ke[0]
    # plane strain: the nodes at z = 0 and z = T move alike in (x, y), u_z = 0; the hex's
    # stiffness per unit thickness is then the Q4's
    sym = np.zeros((24, 8))
    for a in range(4):
        for i in range(2):
            sym[3 * a + i, 2 * a + i] = 1.0
            sym[12 + 3 * a + i, 2 * a + i] = 1.0
    np.testing.assert_allclose(sym.T @ k3 @ sym / 0.05, k2, rtol=1e-12, atol=1e-6 * np.abs(k2).max())


def test_face_pressure_resultant():
    m = hex_specimen(0.04, 0.08, 0.03, 2, 3, 2)
    f = np.zeros(3 * m.n_nodes)
    face_pressure(m.nodes, m.face_sets["left"], 2e4, f)
    f = f.reshape(-1, 3)
    np.testing.assert_allclose(f[m.node_sets["left"]].sum(axis=0), [2e4 * 0.08 * 0.03, 0, 0], atol=1e-12)
    assert np.abs(f[np.setdiff1d(np.arange(m.n_nodes), m.node_sets["left"])]).max() == 0.0


@pytest.mark.parametrize("n", [1, 3])
def test_uncracked_specimen_matches_closed_form_with_confinement(tmp_path, n):
    """F = W (E/(1-nu^2) u/H + nu/(1-nu) p) for plane strain under lateral pressure p."""
    from rockfrac.case.schema import parse_case
    from rockfrac.output.csvout import read_csv
    from rockfrac.runner import run_case

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
    h = hex_specimen(0.04, 0.08, 0.02, 2, 4, 1)
    assert h.check() == [] and h.cells.shape == (8, 8) and h.dim == 3
    assert set(h.node_sets["back"]) | set(h.node_sets["front"]) == set(range(h.n_nodes))
