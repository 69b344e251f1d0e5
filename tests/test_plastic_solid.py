"""Drucker-Prager bulk in the FE engine: homogeneous specimen against the material-point driver
(Q4 and Hex8 in plane strain), element tangent against finite differences, quadratic Newton."""

import numpy as np
import pytest

from rockfrac.case.build import build, drucker_prager_of
from rockfrac.case.schema import parse_case
from rockfrac.elements.plastic_solid import DruckerPragerSolid
from rockfrac.fem.reference import HEX8, QUAD4
from rockfrac.laws.dp_driver import drive_specimen
from rockfrac.laws.drucker_prager_params import DruckerPrager
from rockfrac.mesh import hex_specimen
from rockfrac.output.csvout import read_csv
from rockfrac.runner import run_case

E, NU, P, W, H = 1.5e7, 0.3, 2e4, 0.04, 0.08
LAW = DruckerPrager.from_mohr_coulomb(E, NU, phi=0.5236, c=6000.0, psi=0.087, H=3e5)
DP_BULK = {"model": "drucker_prager", "E": E, "nu": NU, "beta": LAW.beta, "b": LAW.b, "kappa0": LAW.kappa0,
           "H": LAW.H}


def dp_case(element: str, steps: int = 40, u: float = 1e-3) -> dict:
    mesh = {"element": element, "crack": False}
    if element == "hex8":
        mesh = {"element": "hex8", "thickness": 0.05}
    return {"mesh": mesh, "bulk": dict(DP_BULK),
            "loading": {"confinement": P, "confinement_steps": 1, "axial_displacement": u, "axial_steps": steps}}


@pytest.mark.parametrize("element", ["quad4", "hex8"])
def test_homogeneous_specimen_matches_the_material_point_driver(tmp_path, element):
    """The paper's specimen is homogeneous: F_axial(u) must be the driver's -sigma_yy W at eps_yy = -u/H."""
    run_case(parse_case(dp_case(element)), tmp_path)
    h = read_csv(tmp_path / "history.csv")
    ax = h["stage"] == "axial"
    path = drive_specimen(LAW, confinement=P, axial_strain=-1e-3 / H, steps=40, locate=False)
    force = -path.sigma[:, 1] * W
    np.testing.assert_allclose(h["F_axial"][ax], force[2:], rtol=1e-8)
    assert np.any(path.mode[2:] > 0) and force[-1] > force[2]  # yielded and hardening


def test_hex8_plane_strain_equals_q4_with_plasticity(tmp_path):
    run_case(parse_case(dp_case("quad4")), tmp_path / "q")
    run_case(parse_case(dp_case("hex8")), tmp_path / "h")
    hq, hh = read_csv(tmp_path / "q" / "history.csv"), read_csv(tmp_path / "h" / "history.csv")
    np.testing.assert_allclose(hh["F_axial"], hq["F_axial"], rtol=1e-10)
    np.testing.assert_allclose(hh["u_axial"], hq["u_axial"], rtol=1e-12)


@pytest.mark.parametrize("ref", [QUAD4, HEX8])
def test_element_tangent_matches_finite_differences(ref):
    """K = d f_int / d u of a distorted plastic element, central differences."""
    rng = np.random.default_rng(3)
    if ref is QUAD4:
        nodes = np.array([[0.0, 0.0], [0.05, 0.004], [0.047, 0.09], [-0.003, 0.08]])
    else:
        m = hex_specimen(0.04, 0.08, 0.05)
        nodes = m.nodes[m.cells[0]] + rng.uniform(-3e-3, 3e-3, (8, 3))  # in cell order
    cells = np.arange(ref.n_nodes)[None, :]
    law = DruckerPrager(E, NU, LAW.beta, 0.5 * LAW.b, LAW.kappa0, LAW.H)  # b != beta: non-symmetric
    solid = DruckerPragerSolid(nodes, cells, ref, law)
    n = nodes.size
    # a compressive deformation well past yield, plus a random perturbation
    u = (nodes @ np.diag([2e-3, -8e-3, 0.0][: ref.dim])).ravel() + rng.uniform(-1e-5, 1e-5, n)
    ev = solid.evaluate(u, np.zeros(n))
    assert ev.ok and np.any(solid.trial[..., -1] > 0)  # plastic points
    k_fd = np.zeros((n, n))
    h = 1e-9
    for j in range(n):
        e = np.zeros(n)
        e[j] = h
        k_fd[:, j] = (solid.evaluate(u + e, np.zeros(n)).fe[0] - solid.evaluate(u - e, np.zeros(n)).fe[0]) / (2 * h)
    scale = np.abs(ev.ke[0]).max()
    np.testing.assert_allclose(ev.ke[0] / scale, k_fd / scale, atol=1e-6)
    assert np.abs(ev.ke[0] - ev.ke[0].T).max() > 1e-6 * scale  # non-symmetric, as it must be


def test_dp_case_keys_are_validated(tmp_path):
    from rockfrac.case.schema import CaseError

    bad = dp_case("quad4")
    del bad["bulk"]["kappa0"]
    with pytest.raises(CaseError, match=r"\[bulk\].*needs kappa0"):
        parse_case(bad, "c.toml")
    bad = dp_case("quad4")
    bad["bulk"]["model"] = "elastic"
    with pytest.raises(CaseError, match="beta, b, kappa0, H only apply to model = 'drucker_prager'"):
        parse_case(bad, "c.toml")
    bad = dp_case("hex8")
    bad["mesh"]["crack"] = True
    with pytest.raises(CaseError, match="hex8' cannot carry a cohesive crack"):
        parse_case(bad, "c.toml")
    bad = dp_case("quad4")
    bad["bulk"]["H"] = -1e12
    with pytest.raises(CaseError, match="softens too fast"):
        parse_case(bad, "c.toml")
    built = build(parse_case(dp_case("hex8")))
    assert built.thickness == 0.05 and built.model.dim == 3
    assert drucker_prager_of(built.case.bulk) == LAW
