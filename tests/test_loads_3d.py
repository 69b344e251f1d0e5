"""Loads of a 3D loading program on a box of hexahedra or tetrahedra against closed forms: a face pressure, a
face traction, gravity, and an in-situ stress varying with depth that holds the body still and
shifts the loaded response by itself."""

from __future__ import annotations

import numpy as np
import pytest

from rockfrac.api import run
from rockfrac.case.schema import parse_case
from rockfrac.mesh import rock_tests as rt

E, NU, RHO, G = 2e10, 0.25, 2500.0, 9.81
SIZE = (1.0, 2.0, 3.0)  # lx, ly, lz [m]
ROLLERS = {"left": {"x": 0.0}, "front": {"y": 0.0}, "bottom": {"z": 0.0}}


@pytest.fixture(scope="module", params=["hex8", "tet4"])
def box(tmp_path_factory, request):
    return rt.box(tmp_path_factory.mktemp("box") / "box.msh", SIZE, (2, 3, 4), element=request.param)


def case(box, stages, **extra) -> dict:
    return {"title": "box", "mesh": {"kind": "gmsh", "file": str(box)},
            "bulk": {"E": E, "nu": NU, "density": RHO}, "stages": stages,
            "output": {"picture": False}, **extra}


def solve(box, tmp_path, stages, name="o", **extra):
    return run(parse_case(case(box, stages, **extra), "<box>"), tmp_path / name)


def test_face_pressure_on_rollers_is_a_uniform_uniaxial_stress(box, tmp_path):
    p = 4e6
    r = solve(box, tmp_path, [{"name": "press", "displacement": ROLLERS, "pressure": {"top": p}}])
    h, mesh = r.history, r.built.mesh
    lx, ly, lz = SIZE
    u = r.displacement()
    x = mesh.nodes
    # u = (nu p x / E, nu p y / E, -p z / E): exact in trilinear elements
    np.testing.assert_allclose(u, np.stack([NU * p * x[:, 0] / E, NU * p * x[:, 1] / E, -p * x[:, 2] / E], 1),
                               atol=1e-12 * p * lz / E)
    s = r.cell_stress()  # xx, yy, zz, xy, yz, xz
    np.testing.assert_allclose(s[:, 2], -p, rtol=1e-9)
    assert np.abs(s[:, [0, 1, 3, 4, 5]]).max() < 1e-8 * p
    # the rollers carry the load: reaction of the bottom equals the pressure on the top
    assert h["R_bottom_z"][-1] == pytest.approx(p * lx * ly, rel=1e-10)  # the supports push up
    assert h["W_external"][-1] == pytest.approx(0.5 * p * lx * ly * p * lz / E, rel=1e-10)


def test_face_traction_is_balanced_by_the_fixed_bottom(box, tmp_path):
    t = np.array([1e6, -2e6, 5e5])
    fixed = {"bottom": {"x": 0.0, "y": 0.0, "z": 0.0}}
    r = solve(box, tmp_path, [{"name": "shear", "displacement": fixed, "traction": {"top": t.tolist()}}])
    h = r.history
    area = SIZE[0] * SIZE[1]
    for a, comp in enumerate("xyz"):
        assert h[f"R_bottom_{comp}"][-1] == pytest.approx(-t[a] * area, rel=1e-10)
    # it does work only along itself: W = t . mean top displacement x area (uniform traction, nodal
    # forces consistent)
    assert h["W_external"][-1] > 0 and abs(h["energy_error"][-1]) < 1e-10 * h["W_external"][-1]


def oedometric_modulus() -> float:
    return E * (1 - NU) / ((1 + NU) * (1 - 2 * NU))


def test_gravity_on_a_laterally_confined_column_is_exact_at_the_nodes(box, tmp_path):
    """u_z(z) = -rho g (H z - z^2 / 2) / M, M the oedometric modulus: trilinear elements with
    consistent body forces reproduce it at the nodes (the 1D property of linear elements); the
    reaction is exact on both cell types."""
    rollers = {"left": {"x": 0.0}, "right": {"x": 0.0}, "front": {"y": 0.0}, "back": {"y": 0.0},
               "bottom": {"z": 0.0}}
    r = solve(box, tmp_path, [{"name": "weigh", "displacement": rollers, "gravity": [0.0, 0.0, -G]}])
    z = r.built.mesh.nodes[:, 2]
    lz = SIZE[2]
    exact = -RHO * G * (lz * z - 0.5 * z**2) / oedometric_modulus()
    u = r.displacement()
    if r.built.mesh.cell_type == "hex8":
        np.testing.assert_allclose(u[:, 2], exact, atol=1e-10 * np.abs(exact).max())
        assert np.abs(u[:, :2]).max() < 1e-10 * np.abs(exact).max()
    else:  # tetrahedra couple the layers sideways: close on 4 layers, not nodally exact
        np.testing.assert_allclose(u[:, 2], exact, atol=0.04 * np.abs(exact).max())
    area = SIZE[0] * SIZE[1]
    assert r.history["R_bottom_z"][-1] == pytest.approx(RHO * G * area * lz, rel=1e-10)


def test_in_situ_stress_with_depth_holds_still_then_shifts_the_loaded_response(box, tmp_path):
    lz, k0 = SIZE[2], 0.6
    rho_g = RHO * G
    # sigma_zz = -rho g (H - z), sigma_xx = sigma_yy = k0 sigma_zz: in equilibrium with gravity
    initial = {"gravity": [0.0, 0.0, -G],
               "stress": [{"stress": [-k0 * rho_g * lz, -k0 * rho_g * lz, -rho_g * lz, 0.0, 0.0, 0.0],
                           "gradient": [k0 * rho_g, k0 * rho_g, rho_g, 0.0, 0.0, 0.0], "datum": 0.0}]}
    rollers = {"left": {"x": 0.0}, "right": {"x": 0.0}, "front": {"y": 0.0}, "back": {"y": 0.0},
               "bottom": {"z": 0.0}}
    p = 3e6
    stages = [{"name": "hold", "displacement": rollers},
              {"name": "press", "displacement": rollers, "pressure": {"top": p}}]
    r = solve(box, tmp_path, stages, initial=initial)
    h = r.history
    assert list(h["stage"]) == ["hold", "press"]
    u_hold = h["u_top_z"][0]
    assert abs(u_hold) < 1e-14 * lz and abs(h["W_external"][0]) < 1e-6  # nothing moved, nothing worked
    # the pressure alone, without the in-situ stress and gravity
    plain = solve(box, tmp_path, [{"name": "press", "displacement": rollers, "pressure": {"top": p}}], "plain")
    np.testing.assert_allclose(r.displacement(), plain.displacement(), atol=1e-12 * p * lz / E)
    # stresses: the initial field plus the uniform oedometric response
    s = r.cell_stress()
    centres = r.built.mesh.nodes[r.built.mesh.cells].mean(axis=1)
    szz0 = -rho_g * (lz - centres[:, 2])
    np.testing.assert_allclose(s[:, 2], szz0 - p, rtol=1e-9, atol=1e-6 * p)
    lateral = NU / (1 - NU) * p
    np.testing.assert_allclose(s[:, 0], k0 * szz0 - lateral, rtol=1e-9, atol=1e-6 * p)
