"""[cohesive] normals = "smoothed": a faceted surface's normals averaged at its vertices
(rockfrac.elements.interface_points.smoothed_normals), and why surfaces on every edge need it: a
polygonal interface whose vertex copies are tied on both sides locks with each edge's own frame and
slides at the closed-form load with the smoothed one."""

import math

import gmsh
import numpy as np
import pytest
from conftest import paper_case

from rockfrac.case.schema import CaseError, parse_case
from rockfrac.elements.interface_points import InterfacePoints, local_frames_3d, smoothed_normals
from rockfrac.mesh.gmsh_io import gmsh_session
from rockfrac.output.csvout import read_csv


def points_2d(normal_angles, weights, nodes):
    """Points whose normals make ``normal_angles`` [rad] with x, their frames rows (t, n), t = (n_y, -n_x)."""
    n = np.stack([np.cos(normal_angles), np.sin(normal_angles)], axis=1)
    frame = np.stack([np.stack([n[:, 1], -n[:, 0]], axis=1), n], axis=1)
    k = len(normal_angles)
    return InterfacePoints(minus=np.arange(k), plus=np.arange(k, 2 * k), weight=np.asarray(weights, float),
                           frame=frame, x=np.zeros((k, 2)), cell=np.arange(k)), np.asarray(nodes)


def test_a_polygons_vertex_takes_the_weighted_mean_normal_each_point_with_its_own_sign():
    """Two edges at a vertex, 10 degrees either side of vertical, lengths 1 and 2 (the second
    oriented the other way): both take the length-weighted mean, each with its sign; the point alone
    at its node and two edges at right angles keep their own."""
    a, b = math.radians(80.0), math.radians(100.0) + math.pi  # the second normal flipped
    pts, nodes = points_2d(np.array([a, b, 0.3, 0.0, math.pi / 2]), [1.0, 2.0, 2.0, 1.0, 1.0], [7, 7, 8, 9, 9])
    out = smoothed_normals(pts, nodes, math.radians(15.0))
    mean = np.array([math.cos(a), math.sin(a)]) + 2.0 * np.array([math.cos(b - math.pi), math.sin(b - math.pi)])
    mean /= np.linalg.norm(mean)
    np.testing.assert_allclose(out.frame[0, 1], mean, atol=1e-15)
    np.testing.assert_allclose(out.frame[1, 1], -mean, atol=1e-15)
    np.testing.assert_allclose(out.frame[2:], pts.frame[2:], atol=0.0)
    for f in out.frame:  # rotations with rows (t, n), t = (n_y, -n_x) as interface_points makes them
        np.testing.assert_allclose(f @ f.T, np.eye(2), atol=1e-15)
        np.testing.assert_allclose(f[0], [f[1, 1], -f[1, 0]], atol=0.0)


def test_a_vertex_sharper_than_the_smoothing_angle_keeps_its_edges_normals():
    """A 40 degree kink: each normal is about 20 degrees off the mean, above 15 and below 25."""
    pts, nodes = points_2d(np.radians([70.0, 110.0]), [1.0, 1.0], [4, 4])
    np.testing.assert_allclose(smoothed_normals(pts, nodes, math.radians(15.0)).frame, pts.frame, atol=0.0)
    out = smoothed_normals(pts, nodes, math.radians(25.0))
    np.testing.assert_allclose(out.frame[:, 1], [[0.0, 1.0], [0.0, 1.0]], atol=1e-15)


def test_at_a_crossing_each_line_through_the_node_is_smoothed_on_its_own():
    """Four edges at a node: two nearly continuing each other (normals at 90 and 100 degrees, the
    second flipped) and two more (0 and 6 degrees): each line takes its own mean, the lines are not
    mixed; a fifth edge at 45 degrees, near neither within 2 x 15 degrees, keeps its own."""
    angles = np.radians([90.0, 100.0 + 180.0, 0.0, 6.0, 45.0])
    pts, nodes = points_2d(angles, [1.0] * 5, [3] * 5)
    out = smoothed_normals(pts, nodes, math.radians(15.0))
    for i, j, mean in ((0, 1, 95.0), (2, 3, 3.0)):
        np.testing.assert_allclose(out.frame[i, 1], [math.cos(math.radians(mean)), math.sin(math.radians(mean))],
                                   atol=1e-15)
        np.testing.assert_allclose(np.abs(out.frame[j, 1]), np.abs(out.frame[i, 1]), atol=1e-15)
    np.testing.assert_allclose(out.frame[1, 1], -out.frame[0, 1], atol=1e-15)  # its own sign
    np.testing.assert_allclose(out.frame[4], pts.frame[4], atol=0.0)


def test_a_faceted_sheets_node_takes_the_area_weighted_mean_normal_in_3d():
    """Four faces of a shallow pyramid round its apex, tilted 8 degrees: the apex's points take the
    axis (z); the frames stay right-handed rotations."""
    tilt = math.radians(8.0)
    az = np.radians([0.0, 90.0, 180.0, 270.0])
    n = np.stack([math.sin(tilt) * np.cos(az), math.sin(tilt) * np.sin(az), np.full(4, math.cos(tilt))], axis=1)
    pts = InterfacePoints(minus=np.arange(4), plus=np.arange(4, 8), weight=np.full(4, 0.25),
                          frame=local_frames_3d(n), x=np.zeros((4, 3)), cell=np.arange(4))
    out = smoothed_normals(pts, np.zeros(4, dtype=np.int64), math.radians(10.0))
    np.testing.assert_allclose(out.frame[:, 2], np.tile([0.0, 0.0, 1.0], (4, 1)), atol=1e-15)
    for f in out.frame:
        np.testing.assert_allclose(f @ f.T, np.eye(3), atol=1e-15)
        assert np.linalg.det(f) == pytest.approx(1.0, abs=1e-14)


# A stiff inclusion (radius R) in an annulus held on its outer circle, surfaces on every edge of the
# annulus (5x stronger) and on the inclusion's boundary, a polygon of N edges. Eight points inside
# the inclusion are driven: first outwards (the interface is pressed), then also round the centre.
R, OUTER, DRIVEN, SIZE, N_DRIVEN = 0.005, 0.01, 0.002, 0.0013, 8
SQUEEZE, TURN = 5e-7, 0.004  # [m] outwards, [rad] round
LAW = {"law": "bilinear", "sigma_c": 4000.0, "Gc": 1e5, "beta": 0.5}  # in compression: |T_t| <= beta sigma_c


def inclusion_msh(path):
    with gmsh_session("inclusion"):
        occ = gmsh.model.occ
        ring, disc = occ.addDisk(0, 0, 0, OUTER, OUTER), occ.addDisk(0, 0, 0, R, R)
        pieces, _ = occ.fragment([(2, ring)], [(2, disc)])
        driven = [occ.addPoint(DRIVEN * math.cos(a), DRIVEN * math.sin(a), 0)
                  for a in 2 * math.pi * np.arange(N_DRIVEN) / N_DRIVEN]
        occ.synchronize()
        surfaces = [t for d, t in pieces if d == 2]
        inner = [t for t in surfaces if abs(occ.getMass(2, t) - math.pi * R ** 2) < 1e-12]
        annulus = [t for t in surfaces if t not in inner]
        gmsh.model.mesh.embed(0, driven, 2, inner[0])
        gmsh.model.addPhysicalGroup(2, inner, name="inclusion")
        gmsh.model.addPhysicalGroup(2, annulus, name="annulus")
        circle = {c for _, c in gmsh.model.getBoundary([(2, inner[0])], oriented=False)}
        outer = [c for _, c in gmsh.model.getBoundary([(2, t) for t in annulus], oriented=False) if c not in circle]
        gmsh.model.addPhysicalGroup(1, outer, name="outer")
        for k, p in enumerate(driven):
            gmsh.model.addPhysicalGroup(0, [p], name=f"p{k}")
        gmsh.option.setNumber("Mesh.MeshSizeMax", SIZE)
        gmsh.option.setNumber("Mesh.MeshSizeMin", SIZE)
        gmsh.option.setNumber("Mesh.RecombineAll", 1)
        gmsh.model.mesh.generate(2)
        gmsh.write(str(path))
    return path


def inclusion_case(msh, form: str, normals: str) -> dict:
    def section(where, regions, scale):
        s = dict(LAW, form=form, where=where, regions=regions, normals=normals, sigma_c=LAW["sigma_c"] * scale)
        s.update({"kn": 1e13, "kt": 1e13} if form == "ep" else {"augmentation": 1e13})
        return s

    out, turned = {}, {}
    for k, a in enumerate(2 * math.pi * np.arange(N_DRIVEN) / N_DRIVEN):
        x, y = DRIVEN * math.cos(a), DRIVEN * math.sin(a)
        out[f"p{k}"] = {"x": SQUEEZE * math.cos(a), "y": SQUEEZE * math.sin(a)}
        turned[f"p{k}"] = {"x": SQUEEZE * math.cos(a) - TURN * y, "y": SQUEEZE * math.sin(a) + TURN * x}
    return {"title": "a turned inclusion", "mesh": {"kind": "gmsh", "file": str(msh)},
            "materials": [{"region": "inclusion", "model": "elastic", "E": 1e10, "nu": 0.2},
                          {"region": "annulus", "model": "elastic", "E": 1e8, "nu": 0.2}],
            "cohesive": [section("within", ["annulus"], 5.0), section("between", ["annulus", "inclusion"], 1.0)],
            "stages": [{"name": "squeeze", "steps": 2, "displacement": dict(out, outer={"x": 0.0, "y": 0.0})},
                       {"name": "turn", "steps": 10, "displacement": turned}],
            "output": {"vtk": False, "picture": False}}


def torque(history) -> np.ndarray:
    """The driven points' reaction moment about the centre [N m / m]."""
    m = 0.0
    for k, a in enumerate(2 * math.pi * np.arange(N_DRIVEN) / N_DRIVEN):
        m = m + DRIVEN * (math.cos(a) * history[f"R_p{k}_y"] - math.sin(a) * history[f"R_p{k}_x"])
    return np.asarray(m)


@pytest.fixture(scope="module")
def inclusion(tmp_path_factory):
    return inclusion_msh(tmp_path_factory.mktemp("inclusion") / "inclusion.msh")


@pytest.mark.parametrize("form", ["ep", "rp"])
def test_a_turned_inclusion_slides_at_the_closed_form_torque_with_smoothed_normals(inclusion, run, form):
    """Pressed, the polygon's points carry |T_t| <= beta sigma_c whatever their normal traction, so
    the inclusion turns at M = beta sigma_c R P (P: the polygon's perimeter, N chords of the circle),
    the smoothed frames' tangents being perpendicular to the radius at the vertices. Each vertex has
    two points (one per edge, the annulus's copies tied by its surfaces), and both forms slide there
    at M to 1e-5 over the whole turn, every boundary point in compression."""
    h, p, summary = run(inclusion_case(inclusion, form, "smoothed"), f"{form}_smoothed")
    assert summary.result.completed
    boundary = p["set"] == "cohesive 2"
    last = boundary & (p["step"] == p["step"].max())
    n_vertices = int(last.sum()) // 2
    np.testing.assert_allclose(np.hypot(p["x"][last], p["y"][last]), R, rtol=1e-12)
    closed = LAW["beta"] * LAW["sigma_c"] * R * n_vertices * 2.0 * R * math.sin(math.pi / n_vertices)
    turning = h["stage"] == "turn"
    m = torque(h)[turning]
    sliding = m > 0.99 * closed
    assert sliding.sum() >= 8  # it yields early in the turn and slides from there on
    np.testing.assert_allclose(m[sliding], closed, rtol=1e-5)
    assert p["T_n"][last].max() < -1e3
    np.testing.assert_allclose(np.abs(p["T_t"][last]), LAW["beta"] * LAW["sigma_c"], rtol=1e-6)


def test_with_each_edges_own_normal_the_polygon_locks(inclusion, run):
    """The same with normals = 'pairs': a vertex's two points see one jump but flow along their own
    edges' tangents, 360 / N degrees apart, so the vertices cannot slide; the torque climbs past the
    closed form and the turn stops (the annulus's surfaces have to break round them)."""
    h, p, summary = run(inclusion_case(inclusion, "rp", "pairs"), "rp_pairs")
    boundary = p["set"] == "cohesive 2"
    n_vertices = int((boundary & (p["step"] == p["step"].max())).sum()) // 2
    closed = LAW["beta"] * LAW["sigma_c"] * R * n_vertices * 2.0 * R * math.sin(math.pi / n_vertices)
    assert torque(h).max() > 1.05 * closed
    assert not summary.result.completed


def test_smoothing_angle_needs_smoothed_normals():
    """A smoothing angle without normals = 'smoothed' would be ignored: refused by name."""
    case = paper_case("rp")
    case["cohesive"]["smoothing_angle"] = 0.2
    with pytest.raises(CaseError, match="smoothing_angle only applies to normals = 'smoothed'"):
        parse_case(case, "case.toml")
    case["cohesive"]["normals"] = "smoothed"
    assert parse_case(case, "case.toml").cohesive_sets[0].smoothing == 0.2
    case["cohesive"]["smoothing_angle"] = 1.6  # not below 90 degrees
    with pytest.raises(CaseError, match="smoothing_angle"):
        parse_case(case, "case.toml")
