"""Crack tracking of embedded bands: an oblique band seeded at one lateral edge crosses to the other,
straight at its bifurcation angle and continuous, on quads and on an unstructured triangle mesh."""

import math

import gmsh
import numpy as np
import pytest

from rockfrac.case.schema import CaseError, parse_case
from rockfrac.mesh.gmsh_io import gmsh_session
from rockfrac.output.csvout import read_csv
from rockfrac.runner import run_case

W, H = 0.04, 0.08
DP = {"model": "drucker_prager", "E": 1.5e7, "nu": 0.3, "beta": 0.480385, "b": 0.321597, "H": 43802.9}


def band_case(mesh: dict, tracking: dict, weak: str = "weak") -> dict:
    """The band example's rock with a strong (elastic) bulk and a weak seed at the left edge, so that
    the band grows from the seed only, through cells whose stress direction reaches det A = 0;
    cohesion and friction soften to zero (c_r = phi_r = 0)."""
    return {
        "mesh": mesh,
        "materials": [dict(DP, region="bulk", kappa0=15000.0), dict(DP, region=weak, kappa0=7155.9)],
        "embedded": dict({"c_p": "eq28", "c_r": 0.0, "phi_p": 0.5236, "phi_r": 0.0, "psi_p": 0.087,
                          "alpha_c": 5e3, "alpha_phi": 5e3, "alpha_psi": 5e3}, **tracking),
        "loading": {"confinement": 2e4, "axial_displacement": 3e-3, "axial_steps": 150, "control": "path",
                    "path_increment": 2e-5, "max_steps": 400},
        "output": {"vtk": False},
    }


def chain(seg: np.ndarray, tol: float) -> list[int]:
    """The order of the segments (n, 2, 2) along one path, each starting where the previous ends
    (a segment may be stored either way round); asserts there is exactly one such path."""
    ends = np.concatenate([seg[:, 0], seg[:, 1]])
    # the path's two ends are the points that no other segment shares
    shared = [np.sum(np.linalg.norm(ends - p, axis=1) < tol) for p in ends]
    free = [k for k, c in enumerate(shared) if c == 1]
    assert len(free) == 2, f"not one open path: {len(free)} free ends"
    order, k = [], free[0] % len(seg)
    point = seg[k, 0] if free[0] < len(seg) else seg[k, 1]
    for _ in range(len(seg)):
        order.append(k)
        far = seg[k, 1] if np.linalg.norm(seg[k, 0] - point) < tol else seg[k, 0]
        nxt = [j for j in range(len(seg)) if j not in order and
               min(np.linalg.norm(seg[j, 0] - far), np.linalg.norm(seg[j, 1] - far)) < tol]
        if not nxt:
            break
        point, k = far, nxt[0]
    assert len(order) == len(seg), "the segments do not form one continuous path"
    return order


def check_band(out, s, max_deviation_deg: float, reach: float = W):
    """One continuous path from the left edge to x = reach (default: the right edge), each segment
    within max_deviation_deg of the first cell's bifurcation angle; returns (onset angle, angles) [deg]."""
    emb = s.built.embeddeds
    seg = np.vstack([g.segments[g.localized()] for g in emb])
    chain(seg, 1e-9 * W)
    xs = seg[..., 0]
    assert xs.min() == pytest.approx(0.0, abs=1e-9) and xs.max() >= reach - 1e-9
    d = seg[:, 1] - seg[:, 0]
    angles = np.degrees(np.arctan2(np.abs(d[:, 1]), np.abs(d[:, 0]) * np.sign(d[:, 0] * d[:, 1] + 1e-300)))
    first = [o for g in emb for o in g.onsets]
    onset = math.degrees(first[0].band_angle)
    assert np.max(np.abs(angles - onset)) < max_deviation_deg
    return onset, angles


@pytest.fixture(scope="module")
def quad_runs(tmp_path_factory):
    mesh = {"kind": "block", "element": "quad4", "width": W, "height": H, "nx": 12, "ny": 24,
            "inclusion": [0.0, 0.0067, 0.0034, 0.0167]}
    out = {}
    for name, tracking in {"local": {"tracking": "local"},
                           "nonlocal": {"tracking": "nonlocal", "tracking_length": 0.01}}.items():
        d = tmp_path_factory.mktemp(name)
        case = band_case(mesh, tracking)
        # to 1.2 mm at the same load step (2e-5 m): the nonlocal band has crossed by 0.85 mm and the
        # force fallen to 0.3 of its peak by 1.0 mm; the local band's run stops near 1.23 mm
        case["loading"].update(axial_displacement=1.2e-3, axial_steps=60)
        case["output"]["picture"] = False  # no crack_map.png: nothing here looks at it
        out[name] = (d, run_case(parse_case(case), d))
    return out


def test_nonlocal_tracking_crosses_the_specimen_straight_and_continuous(quad_runs):
    """The band from the seed at the left edge reaches the right edge (at 57 degrees it rises 1.54
    times the width, 62 mm, inside the 80 mm height) as one continuous path within 3 degrees of its
    bifurcation angle; the specimen softens toward the residual."""
    out, s = quad_runs["nonlocal"]
    assert s.result.completed
    onset, _ = check_band(out, s, 3.0)
    assert 54.0 < onset < 59.0
    h = read_csv(out / "history.csv")
    assert h["F_axial"][-1] < 0.6 * h["F_axial"].max()


def test_local_tracking_keeps_a_continuous_path(quad_runs):
    """Local tracking (each tip cell's own stress) also gives one continuous path."""
    out, s = quad_runs["local"]
    emb = s.built.embeddeds
    chain(np.vstack([g.segments[g.localized()] for g in emb]), 1e-9 * W)


def triangle_block(path, size: float, seed: tuple[float, float, float, float] = (0.0, 0.007, 0.004, 0.015)):
    """An unstructured triangle mesh of the W x H block with a weak seed (regions bulk, weak; the seed
    the rectangle (x0, y0, x1, y1) [m] at the left edge) and the boundary groups of the block kind."""
    x0, y0, x1, y1 = seed
    with gmsh_session("band"):
        occ = gmsh.model.occ
        block = occ.addRectangle(0, 0, 0, W, H)
        weak = occ.addRectangle(x0, y0, 0, x1 - x0, y1 - y0)
        occ.fragment([(2, block)], [(2, weak)])
        occ.synchronize()
        e = 1e-5  # boxes larger than OCC's bounding-box tolerance, far below the seed's size
        inner = [t for _, t in gmsh.model.getEntitiesInBoundingBox(x0 - e, y0 - e, -e, x1 + e, y1 + e, e, dim=2)]
        outer = [t for _, t in gmsh.model.getEntities(2) if t not in inner]
        gmsh.model.addPhysicalGroup(2, inner, name="weak")
        gmsh.model.addPhysicalGroup(2, outer, name="bulk")
        for name, (x0, y0, x1, y1) in {"bottom": (-e, -e, W + e, e), "top": (-e, H - e, W + e, H + e),
                                       "left": (-e, -e, e, H + e), "right": (W - e, -e, W + e, H + e)}.items():
            found = gmsh.model.getEntitiesInBoundingBox(x0, y0, -e, x1, y1, e, dim=1)
            gmsh.model.addPhysicalGroup(1, [t for _, t in found], name=name)
        gmsh.model.addPhysicalGroup(0, [t for _, t in gmsh.model.getEntitiesInBoundingBox(
            -e, -e, -e, e, e, e, dim=0)], name="bottom_left")
        gmsh.option.setNumber("Mesh.MeshSizeMax", size)
        gmsh.option.setNumber("Mesh.Algorithm", 6)
        gmsh.model.mesh.generate(2)
        gmsh.write(str(path))
    return path


def test_nonlocal_tracking_on_an_unstructured_triangle_mesh(tmp_path):
    """On an unstructured Gmsh triangle mesh the path is continuous (each segment's end is its
    neighbour's start), crosses from the left edge to within 2 mm of the right edge (95 % of the
    width) and stays within 3 degrees of the bifurcation angle.

    Known limit (issue 15): Newton does not converge when the last cell, at the right edge, is cut
    (the run stops there, cleanly, after about 140 steps), so the test checks the path up to there."""
    msh = triangle_block(tmp_path / "block.msh", 0.003)
    case = band_case({"kind": "gmsh", "file": str(msh)}, {"tracking": "nonlocal", "tracking_length": 0.005})
    case["output"]["picture"] = False  # no crack_map.png: nothing here looks at it
    s = run_case(parse_case(case), tmp_path / "out")
    assert s.result.steps > 100
    check_band(tmp_path / "out", s, 3.0, reach=W - 0.002)


@pytest.mark.parametrize("tracking,expected", [
    ({"tracking": "nonlocal"}, "tracking = 'nonlocal' needs tracking_length [m]"),
    ({"tracking": "local", "tracking_length": 0.01}, "tracking_length only applies to tracking = 'nonlocal'"),
    ({"tracking": "global"}, "tracking"),
])
def test_tracking_keys_are_checked(tracking, expected):
    mesh = {"kind": "block", "element": "quad4", "width": W, "height": H, "nx": 4, "ny": 8,
            "inclusion": [0.0, 0.0, 0.01, 0.01]}
    with pytest.raises(CaseError) as err:
        parse_case(band_case(mesh, tracking), "band.toml")
    assert expected in str(err.value) and "band.toml" in str(err.value)
