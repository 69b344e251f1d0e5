"""Nodal embedded cracks under gravity (issue 15): the enrichment's share of the body forces, and an
in-situ stress that varies with depth.

- A lithostatic in-situ stress (linear in the elevation, with shear) balanced by gravity, a crack given
  across the block after it is set: u = 0, q = 0 is the exact solution on quads, triangles and
  tetrahedra. It needs three things, each tested to fail without it: the enriched part of the body
  force (int (H - H_a) N_a rho g over the cut cells' sides), the side points' and crack points'
  stress at their own place (the field's variation from the Gauss point), and the in-situ traction's
  share on the boundary sides the crack crosses integrated as the linear field it is.
- A block resting on a horizontal crack, gravity switched on in a stage: the crack carries the weight
  above it at every point, T_n = -rho g (H - y_c), its jump T_n / kn.
"""

import numpy as np
import pytest

from rockfrac.case.build import build
from rockfrac.case.schema import parse_case
from rockfrac.laws import embedded_penalty as EP
from rockfrac.mesh import rock_tests as rt
from rockfrac.runner import run_case
from rockfrac.solve.stepping import _EnrichedLoads

W, H = 0.04, 0.08
RHO, G = 1e5, 50.0  # a steep gradient (rho g = 5 MPa/m) against stresses of 1 MPa
K = 1e11
DP = {"model": "drucker_prager", "E": 1.5e7, "nu": 0.3, "beta": 0.480385, "b": 0.321597, "H": 43802.9,
      "kappa0": 1e8, "density": RHO}  # never yields
LAW = {"c_r": 0.0, "phi_p": 0.5236, "phi_r": 0.0, "psi_p": 0.087, "alpha_c": 5e3, "alpha_phi": 5e3, "alpha_psi": 5e3}


def lithostatic(dim: int) -> dict:
    """sigma0 at the base and its gradient with the elevation: d sigma_vv / de = rho g balances gravity,
    the horizontal stresses grow at half the rate, one constant shear."""
    if dim == 2:
        return {"stress": [-8e5, -1e6, -9e5, 1e5], "gradient": [0.5 * RHO * G, RHO * G, 0.5 * RHO * G, 0.0]}
    return {"stress": [-8e5, -7e5, -1e6, 1e5, -5e4, 8e4],
            "gradient": [0.5 * RHO * G, 0.4 * RHO * G, RHO * G, 0.0, 0.0, 0.0]}


def case_2d(element: str, crack: list, stages: list) -> dict:
    return {
        "mesh": {"kind": "block", "element": element, "width": W, "height": H, "nx": 6, "ny": 12},
        "materials": [dict(DP, region="bulk")],
        "embedded": dict(LAW, kinematics="nodal", kn=K, kt=K, tracking="local",
                         cracks=[{"points": crack, "c_p": 1e8}]),
        "stages": stages, "output": {"vtk": False},
    }


def share_parts(built):
    """f0 with the enrichment's shares, and the shares of the in-situ tractions and of gravity apart."""
    model, first = built.model, built.program.stages[0]
    f0 = built.program.f0
    own = f0.copy()
    _EnrichedLoads(model, built.program.stages, f0)()
    body = model.enriched_body_forces(first.start_body_force)
    return f0, f0 - own - body, body


def residual_at_rest(built, f):
    model = built.model
    u = built.program.u0.copy()
    model.begin_step()
    r = model.assemble(u, u, f).residual
    r[model.dirichlet] = 0.0
    return r


@pytest.mark.parametrize("element", ["quad4", "tri3"])
def test_lithostatic_stress_with_a_crack_across_is_an_equilibrium(element):
    case = case_2d(element, [[0.0, 0.0213], [W, 0.0213 + 0.7 * W]], [
        {"name": "hold", "displacement": {"bottom": {"y": 0.0}, "bottom_left": {"x": 0.0}}}])
    case["initial"] = {"stress": [lithostatic(2)], "gravity": [0.0, -G]}
    built = build(parse_case(case))
    g = built.embeddeds[0]
    g.registry.refresh()
    assert g.registry.enriched.sum() > 0 and g.cc_cell.size >= 6
    # every side point carries sigma0 where it lies, every crack point sigma0 . n there
    spec = lithostatic(2)
    used = g.cc_w > 0
    y = np.zeros(g.cc_w.shape)
    for c, e in enumerate(g.cc_cell):  # the side points' places from their shape values
        y[c] = g.cc_nside[c] @ g.x[e, :, 1]
    expected = np.array(spec["stress"])[[0, 1, 3]] + y[..., None] * np.array(spec["gradient"])[[0, 1, 3]]
    np.testing.assert_allclose(g.cc_sigma[..., [0, 1, 3]][used], expected[used], rtol=1e-12, atol=1e-6)
    f0, traction_share, body_share = share_parts(built)
    scale = RHO * G * (W / 6) * (H / 12)  # a cell's weight [N/m]
    assert np.abs(body_share).max() > 1e-2 * scale
    r = residual_at_rest(built, f0)
    assert np.abs(r).max() <= 1e-9 * scale
    # without gravity's share on the enrichment, or with the boundary sides' traction taken at their
    # centres (uniform), u = 0 is not the solution
    assert np.abs(residual_at_rest(built, f0 - body_share)).max() > 1e-2 * scale
    first = built.program.stages[0]
    centre = np.repeat(first.start_tractions.mean(axis=1, keepdims=True), 2, axis=1)
    uniform = built.model.enriched_surface_forces(first.start_edges, centre)
    assert np.abs(residual_at_rest(built, f0 - traction_share + uniform)).max() > 1e-3 * scale


def test_cut_cells_without_the_stress_variation_are_out_of_balance(monkeypatch):
    """The side and crack points taking their Gauss point's (the cell's mean) stress, as before: the
    lithostatic block is not at rest (the check that the variation is what makes it exact)."""
    from rockfrac.elements.ede import EmbeddedDruckerPrager
    from rockfrac.elements.ede_nodal import NodalEmbeddedDruckerPrager

    monkeypatch.setattr(NodalEmbeddedDruckerPrager, "set_initial_stress", EmbeddedDruckerPrager.set_initial_stress)
    case = case_2d("quad4", [[0.0, 0.0213], [W, 0.0213 + 0.7 * W]], [
        {"name": "hold", "displacement": {"bottom": {"y": 0.0}, "bottom_left": {"x": 0.0}}}])
    case["initial"] = {"stress": [lithostatic(2)], "gravity": [0.0, -G]}
    built = build(parse_case(case))
    f0, _, _ = share_parts(built)
    assert np.abs(residual_at_rest(built, f0)).max() > 1e-2 * RHO * G * (W / 6) * (H / 12)


@pytest.mark.parametrize("element", ["tet4", "hex8"])
def test_lithostatic_stress_with_a_plane_across_in_3d(tmp_path, element):
    """The same in 3D, on tetrahedra and on hexahedra (whose cut cells' sub-tetrahedra integrate the
    trilinear shape functions' gradients against the linear stress with a rule of degree 3)."""
    from test_nodal_3d import nodal_plane

    msh = rt.box(tmp_path / "box.msh", (W, W, H), (4, 1, 8), element=element)
    case = nodal_plane(msh)
    case.pop("loading", None)
    case["bulk"] = dict(case["bulk"], density=RHO, kappa0=1e8)
    case["embedded"]["cracks"] = [dict(c, c_p=1e8) for c in case["embedded"]["cracks"]]
    case["initial"] = {"stress": [lithostatic(3)], "gravity": [0.0, 0.0, -G]}
    case["stages"] = [{"name": "hold", "displacement": {"bottom": {"z": 0.0}, "bottom_left": {"x": 0.0},
                                                        "front": {"y": 0.0}}}]
    built = build(parse_case(case))
    assert built.embeddeds[0].registry.refresh() and built.embeddeds[0].registry.enriched.sum() > 0
    f0, _, body_share = share_parts(built)
    scale = RHO * G * (W / 4) ** 2 * (H / 8)
    assert np.abs(body_share).max() > 1e-2 * scale
    r = np.abs(residual_at_rest(built, f0)).max()
    assert r <= 1e-9 * scale, r / scale
    assert np.abs(residual_at_rest(built, f0 - body_share)).max() > 1e-2 * scale


def test_a_block_on_a_horizontal_crack_carries_its_weight(tmp_path):
    y_c = 0.0313  # inside a row of cells
    case = case_2d("quad4", [[0.0, y_c], [W, y_c]], [
        {"name": "gravity", "steps": 2, "gravity": [0.0, -G],
         "displacement": {"bottom": {"y": 0.0}, "left": {"x": 0.0}, "right": {"x": 0.0}}}])
    case["output"] = {"vtk": False, "picture": False}
    out = run_case(parse_case(case), tmp_path / "o")
    assert out.result.completed, out.result.message
    g = out.built.embeddeds[0]
    weight = -RHO * G * (H - y_c)  # the normal traction of the block above [Pa]
    used = g.cc_wk > 0
    t = g.cc_cp[..., EP.CP_T:EP.CP_T + 2][used]
    j = g.cc_cp[..., EP.CP_J:EP.CP_J + 2][used]
    np.testing.assert_allclose(t[:, 1], weight, rtol=1e-9)
    np.testing.assert_allclose(t[:, 0], 0.0, atol=1e-9 * abs(weight))
    np.testing.assert_allclose(j[:, 1], weight / K, rtol=1e-9)
