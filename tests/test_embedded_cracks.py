"""Embedded cracks present from the start ([[embedded.cracks]]): the oblique-band patch test.

A straight crack across the specimen from one lateral edge to the other, its cohesion and friction
softening to zero: the two blocks slide apart rigidly and the axial force tends to the closed-form
residual, the confinement times the width (EDE_NOTES' Mohr-Coulomb formula with c = phi = 0). A
formulation that locks (stress carried across the band by the cells' constant jumps) fails it; so do
cut cells whose + sides disagree. On quads and on an unstructured Gmsh triangle mesh, at two angles.
"""

import math

import numpy as np
import pytest

from rockfrac.case.schema import CaseError, parse_case
from rockfrac.output.csvout import read_csv
from rockfrac.runner import run_case

W, H, P = 0.04, 0.08, 2e4
DP = {"model": "drucker_prager", "E": 1.5e7, "nu": 0.3, "beta": 0.480385, "b": 0.321597, "H": 43802.9,
      "kappa0": 1e7}  # never yields: the rock stays elastic, only the crack slides


def crack_case(mesh: dict, angle_deg: float, y0: float, c_p: float = 5e3) -> dict:
    rise = W * math.tan(math.radians(angle_deg))
    return {
        "mesh": mesh,
        "materials": [dict(DP, region=r) for r in (["bulk", "weak"] if mesh.get("kind") == "block" else ["bulk"])],
        "embedded": {"c_r": 0.0, "phi_p": 0.5236, "phi_r": 0.0, "psi_p": 0.087, "alpha_c": 5e3, "alpha_phi": 5e3,
                     "alpha_psi": 5e3, "cracks": [{"points": [[0.0, y0], [W, y0 + rise]], "c_p": c_p}]},
        "loading": {"confinement": P, "axial_displacement": 2e-3, "axial_steps": 100, "control": "path",
                    "path_increment": 2e-5, "max_steps": 400},
        "output": {"vtk": False},
    }


def block(nx: int, ny: int) -> dict:
    return {"kind": "block", "element": "quad4", "width": W, "height": H, "nx": nx, "ny": ny,
            "inclusion": [0.0, 0.0, W / nx, H / ny]}  # a corner cell (the block kind's "weak" region)


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    out = {}
    for name, mesh, angle, y0 in [("10x20 at 56", block(10, 20), 56.0, 0.01013),
                                  ("20x40 at 56", block(20, 40), 56.0, 0.01013),
                                  ("20x40 at 45", block(20, 40), 45.0, 0.02017)]:
        d = tmp_path_factory.mktemp("crack")
        out[name] = (run_case(parse_case(crack_case(mesh, angle, y0)), d), read_csv(d / "history.csv"))
    return out


@pytest.mark.parametrize("name", ["10x20 at 56", "20x40 at 56", "20x40 at 45"])
def test_straight_crack_slides_to_the_closed_form_residual(runs, name):
    """After full softening the force is the confinement times the width within 0.5 %, every cell's
    jump is the same (rigid sliding) and its shear traction is zero."""
    s, h = runs[name]
    assert s.result.completed
    assert h["F_axial"].max() > 3 * P * W  # the crack held first: a real peak, then softening
    assert h["F_axial"][-1] == pytest.approx(P * W, rel=5e-3)
    emb = s.built.embeddeds
    rec = {k: np.concatenate([g.records()[k] for g in emb]) for k in ("jump_t", "jump_n", "T_t", "c", "tan_phi")}
    assert np.all(rec["c"] < 1e-3 * 5e3) and np.all(rec["tan_phi"] < 1e-3)
    jt = rec["jump_t"]
    assert np.ptp(jt) < 1e-3 * np.abs(jt).max()  # one rigid sliding
    assert np.abs(rec["T_t"]).max() < 1e-3 * P


def test_two_meshes_trace_the_same_post_peak_curve(runs):
    """The 10 x 20 and 20 x 40 meshes give the same force at equal top displacement after the peak
    (within 5 %): no mesh dependence of a crack given in advance."""
    (_, a), (_, b) = runs["10x20 at 56"], runs["20x40 at 56"]
    ua, fa = a["u_axial"][a["stage"] == "axial"], a["F_axial"][a["stage"] == "axial"]
    ub, fb = b["u_axial"][b["stage"] == "axial"], b["F_axial"][b["stage"] == "axial"]
    peak = ua[np.argmax(fa)]
    grid = np.linspace(peak, min(ua.max(), ub.max()), 40)[1:]
    order_a, order_b = np.argsort(ua), np.argsort(ub)
    ga = np.interp(grid, ua[order_a], fa[order_a])
    gb = np.interp(grid, ub[order_b], fb[order_b])
    assert np.max(np.abs(ga - gb) / gb) < 0.05


def test_straight_crack_on_an_unstructured_triangle_mesh(tmp_path):
    """The same patch test on a Gmsh triangle mesh (cells cut anywhere, not along a grid)."""
    from test_crack_tracking import triangle_block

    msh = triangle_block(tmp_path / "b.msh", 0.003)
    case = crack_case({"kind": "gmsh", "file": str(msh)}, 60.0, 0.00511)
    case["materials"] = [dict(DP, region="bulk"), dict(DP, region="weak")]
    s = run_case(parse_case(case), tmp_path / "out")
    assert s.result.completed
    h = read_csv(tmp_path / "out" / "history.csv")
    assert h["F_axial"][-1] == pytest.approx(P * W, rel=5e-3)
    seg = np.vstack([g.segments[g.localized()] for g in s.built.embeddeds])
    d = seg[:, 1] - seg[:, 0]
    assert np.allclose(np.degrees(np.arctan2(np.abs(d[:, 1]), np.abs(d[:, 0]))), 60.0, atol=1e-9)


def test_joint_example_slides_at_the_closed_form_load(tmp_path):
    """examples/joint: an inclined Mohr-Coulomb joint without softening (c = 5 kPa, phi = 30 deg)
    that passes exactly through mesh nodes; once it slides the force stays at the closed form
    W [c + p (sin cos + tan(phi) cos^2)] / (sin cos - tan(phi) sin^2) to round-off."""
    from pathlib import Path

    from rockfrac.case.schema import load_case

    path = Path(__file__).resolve().parents[1] / "examples" / "joint" / "joint.toml"
    s = run_case(load_case(path), tmp_path)
    h = read_csv(tmp_path / "history.csv")
    normal = math.pi / 2 - math.atan2(0.05, 0.04)
    sn, cs, tphi = math.sin(normal), math.cos(normal), math.tan(0.5236)
    closed = W * (5000.0 + P * (sn * cs + tphi * cs**2)) / (sn * cs - tphi * sn**2)
    sliding = h["F_axial"] > 0.999 * closed
    assert sliding.sum() >= 20  # a plateau, reached half way
    np.testing.assert_allclose(h["F_axial"][sliding], closed, rtol=1e-8)
    nodes = s.built.mesh.nodes
    on_joint = np.abs((nodes[:, 1] - 0.015) - 1.25 * nodes[:, 0]) < 1e-12
    assert on_joint.sum() >= 5  # the case of nodes on the crack is the one tested


@pytest.mark.parametrize("crack,expected", [
    ({"points": [[0.0, 0.01], [0.05, 0.07]], "c_p": 1e3}, "of its length is not across cells that may localize"),
    ({"points": [[0.0, 0.01]], "c_p": 1e3}, "points"),
    ({"points": [[0.0, 0.01], [0.0, 0.01]], "c_p": 1e3}, "two consecutive points are the same"),
    ({"points": [[0.0, 0.01, 0.0], [0.04, 0.05, 0.0]], "c_p": 1e3}, "points must be [x, y] pairs"),
    ({"points": [[0.0, 0.01], [0.04, 0.05]]}, "c_p"),
])
def test_bad_cracks_are_refused_with_the_key(tmp_path, crack, expected):
    from rockfrac.case.build import build

    case = crack_case(block(4, 8), 45.0, 0.01)
    case["embedded"]["cracks"] = [crack]
    with pytest.raises(CaseError) as err:
        build(parse_case(case, "c.toml"), "c.toml")
    assert expected in str(err.value) and "c.toml" in str(err.value)
