"""3D solids on tetrahedra (tet4) and hexahedra (hex8) in general 3D: patch tests, the read and
orientation of Gmsh tetrahedra and their triangular faces, face loads on triangles, and the
triaxial test of examples/rock_tests/triaxial against its closed forms."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from rockfrac.api import run
from rockfrac.case.schema import load_case
from rockfrac.elements.solid import ElasticSolid
from rockfrac.fem.kinematics import elastic_blocks, element_gradients
from rockfrac.fem.loads import face_pressure, face_stress_traction
from rockfrac.fem.reference import TET4
from rockfrac.laws.elastic import isotropic_elasticity
from rockfrac.mesh import rock_tests as rt
from rockfrac.mesh.gmsh_io import read_mesh
from rockfrac.mesh.topology import boundary_faces, cell_sides, on_boundary
from rockfrac.model import Model
from rockfrac.solve.linear import SuperLU
from rockfrac.solve.newton import Loads, NewtonOptions, newton_step

E, NU = 2e10, 0.25
TRIAXIAL = Path(__file__).resolve().parents[1] / "examples" / "rock_tests" / "triaxial"


@pytest.fixture(scope="module")
def cylinder(tmp_path_factory):
    return read_mesh(rt.cylinder(tmp_path_factory.mktemp("cyl") / "cyl.msh", element_size=0.01), dim=3)


def face_normals(nodes, faces):
    """(k, 3) area vectors of triangles by the right-hand rule."""
    x = nodes[faces]
    return 0.5 * np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0])


def test_tet4_mesh_from_gmsh_is_oriented_and_its_faces_point_out(cylinder):
    m = cylinder
    assert m.cell_type == "tet4" and m.check() == []
    x = m.nodes[m.cells]
    vol = np.einsum("ki,ki->k", np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]), x[:, 3] - x[:, 0]) / 6
    assert vol.min() > 0
    # the volume of the faceted cylinder by the divergence theorem over its outward boundary faces
    faces = boundary_faces(m)
    assert faces.shape[1] == 3
    xc = m.nodes[faces].mean(axis=1)
    assert np.einsum("ki,ki->", xc, face_normals(m.nodes, faces)) / 3 == pytest.approx(vol.sum(), rel=1e-12)
    # every named face set is on the boundary, outward: top up, bottom down, side radial
    for name, direction in (("top", [0, 0, 1]), ("bottom", [0, 0, -1])):
        n = face_normals(m.nodes, m.face_sets[name])
        assert on_boundary(m, m.face_sets[name]).all()
        np.testing.assert_allclose(n / np.linalg.norm(n, axis=1)[:, None], np.broadcast_to(direction, n.shape),
                                   atol=1e-12)
    side = m.face_sets["side"]
    radial = m.nodes[side].mean(axis=1) * [1, 1, 0]
    assert (np.einsum("ki,ki->k", face_normals(m.nodes, side), radial) > 0).all()
    # every cell side is shared by at most two cells; 4 faces per tetrahedron
    assert cell_sides(m.cells, 3).shape == (4 * len(m.cells), 3)


def test_mirrored_tetrahedra_are_reordered(tmp_path):
    import gmsh

    from rockfrac.mesh.gmsh_io import gmsh_session, mesh_from_model

    with gmsh_session("mirror"):
        gmsh.model.occ.addBox(0, 0, 0, 1, 1, 1)
        gmsh.model.occ.mirror([(3, 1)], 1, 0, 0, 0)  # x -> -x
        gmsh.model.occ.synchronize()
        gmsh.option.setNumber("Mesh.MeshSizeMax", 0.5)
        gmsh.model.mesh.generate(3)
        raw = mesh_from_model(dim=3, source="mirror")
    x = raw.nodes[raw.cells]
    vol = np.einsum("ki,ki->k", np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]), x[:, 3] - x[:, 0])
    assert vol.min() > 0 and raw.check() == []
    assert np.sum(vol) / 6 == pytest.approx(1.0, rel=1e-12)


def test_tet4_patch_test_reproduces_a_linear_field_exactly(cylinder):
    """An unstructured tetrahedral cylinder, u = A x + c on its boundary nodes: the interior nodes
    take the same linear field and every cell the one stress C eps."""
    m = cylinder
    boundary = np.unique(boundary_faces(m))
    assert 0 < boundary.size < m.n_nodes
    a = np.array([[1e-3, 2e-4, -1e-4], [-3e-4, 5e-4, 2e-4], [1e-4, -2e-4, -4e-4]])
    bulk = ElasticSolid(m.nodes, m.cells, TET4, E, NU)
    dirichlet = np.sort((3 * boundary[:, None] + np.arange(3)).ravel())
    model = Model(m.n_nodes, [bulk], dirichlet, dim=3)
    exact = (m.nodes @ a.T + 1e-4 * np.arange(1, 4)).ravel()
    zero = np.zeros(model.n_dofs)
    res = newton_step(model, zero, 0.0, 1.0, Loads(np.zeros(dirichlet.size), exact[dirichlet], zero, zero),
                      SuperLU(), NewtonOptions())
    assert res.converged
    np.testing.assert_allclose(res.u, exact, rtol=0, atol=1e-16)
    eps = np.array([a[0, 0], a[1, 1], a[2, 2], a[0, 1] + a[1, 0], a[1, 2] + a[2, 1], a[0, 2] + a[2, 0]])
    sigma = bulk.stresses(res.u)
    assert sigma.shape == (len(m.cells), 1, 6)
    np.testing.assert_allclose(sigma, np.broadcast_to(isotropic_elasticity(E, NU) @ eps, sigma.shape), rtol=1e-9,
                               atol=1e-9 * E * np.abs(eps).max())


def test_tet4_stiffness_is_symmetric_with_six_rigid_modes(cylinder):
    m = cylinder
    grads, wdet = element_gradients(m.nodes[m.cells[:50]], TET4)
    np.testing.assert_allclose(wdet.sum(axis=1), [np.linalg.det(x[1:] - x[0]) / 6 for x in m.nodes[m.cells[:50]]],
                               rtol=1e-12)
    for k in elastic_blocks(grads, wdet, isotropic_elasticity(E, NU)):
        np.testing.assert_allclose(k, k.T, rtol=1e-12, atol=1e-9 * np.abs(k).max())
        w = np.linalg.eigvalsh(k)
        assert np.sum(np.abs(w) < 1e-9 * w.max()) == 6


def test_loads_on_triangular_faces_are_the_exact_integrals(cylinder):
    m = cylinder
    top = m.face_sets["top"]
    area = np.linalg.norm(face_normals(m.nodes, top), axis=1).sum()
    f = np.zeros(3 * m.n_nodes)
    face_pressure(m.nodes, top, 2e6, f)
    np.testing.assert_allclose(f.reshape(-1, 3).sum(axis=0), [0, 0, -2e6 * area], rtol=1e-13, atol=1e-9)
    # a stress varying linearly in x and y on the top: the resultant and its moment are integrals
    # of linear and quadratic functions on each flat triangle; the mid-edge rule (another rule exact
    # for quadratics) gives them independently
    def stress(x):
        s = np.zeros((len(x), 6))
        s[:, 2] = 1e6 * (1 + 30 * x[:, 0] - 50 * x[:, 1])
        s[:, 5] = 4e5 * (1 + 20 * x[:, 1])  # xz: a shear traction on the top
        return s
    f = np.zeros(3 * m.n_nodes)
    face_stress_traction(m.nodes, top, stress, f)
    fn = f.reshape(-1, 3)
    bary = np.array([[0.5, 0.5, 0.0], [0.0, 0.5, 0.5], [0.5, 0.0, 0.5]])
    pts = np.einsum("qa,kai->kqi", bary, m.nodes[top])
    da = np.linalg.norm(face_normals(m.nodes, top), axis=1)[:, None] / 3 * np.ones(3)
    s = stress(pts.reshape(-1, 3)).reshape(len(top), 3, 6)
    t = np.stack([s[..., 5], s[..., 4], s[..., 2]], axis=-1)  # sigma . (0, 0, 1)
    resultant = np.einsum("kqi,kq->i", t, da)
    np.testing.assert_allclose(fn.sum(axis=0), resultant, rtol=1e-12, atol=1e-12 * np.abs(resultant).max())
    moment = np.einsum("kqi,kq->i", np.cross(pts, t), da)  # sum x_a x f_a = int x x t (x = N_a x_a)
    np.testing.assert_allclose(np.cross(m.nodes, fn).sum(axis=0), moment, rtol=1e-12,
                               atol=1e-12 * np.abs(moment).max())


@pytest.fixture(scope="module")
def triaxial(tmp_path_factory):
    case = load_case(TRIAXIAL / "drucker_prager.toml")
    return case, run(case, tmp_path_factory.mktemp("triaxial"))


def test_triaxial_drucker_prager_cylinder_meets_its_closed_forms(triaxial):
    """Homogeneous stress at every Gauss point: confinement, elastic slope E, the yield plateau and
    the radial-to-axial plastic strain ratio of the flow rule (examples/rock_tests/triaxial)."""
    case, r = triaxial
    beta, b, k0, p = case.bulk.beta, case.bulk.b, case.bulk.kappa0, 5e6
    s3 = math.sqrt(3.0)
    q_yield = (p * (1 + 2 * beta / s3) + s3 * k0) / (1 - beta / s3)
    assert q_yield == pytest.approx(39.45e6, rel=1e-3)
    h, mesh = r.history, r.built.mesh
    bottom = mesh.face_sets["bottom"]
    area = np.linalg.norm(face_normals(mesh.nodes, bottom), axis=1).sum()
    sigma_a = np.asarray(h["R_bottom_z"]) / area  # axial compression [Pa]
    height = 0.1
    eps_a = -(np.asarray(h["u_top_z"]) - h["u_top_z"][0]) / height
    elastic = sigma_a < q_yield * (1 - 1e-9)
    plastic = ~elastic
    assert elastic[:5].all() and plastic[-5:].all()
    # elastic: d sigma_a / d eps_a = E under a constant lateral stress
    se, ee = sigma_a[elastic], eps_a[elastic]
    np.testing.assert_allclose(np.diff(se) / np.diff(ee), E, rtol=1e-9)
    assert se[0] == pytest.approx(p + E * ee[0], rel=1e-9)
    np.testing.assert_allclose(sigma_a[plastic][1:], q_yield, rtol=1e-9)
    # the final state at every Gauss point
    s = r.cell_stress()
    expected = np.array([-p, -p, -q_yield, 0, 0, 0])
    np.testing.assert_allclose(s, np.broadcast_to(expected, s.shape), atol=1e-8 * q_yield)
    # total strain from the (linear) displacement field, elastic strain from the stress
    u = r.displacement()
    grad = np.linalg.lstsq(np.column_stack([mesh.nodes, np.ones(mesh.n_nodes)]), u, rcond=None)[0][:3].T
    eps_r, eps_z = grad[0, 0], grad[2, 2]
    assert grad[1, 1] == pytest.approx(eps_r, rel=1e-9)
    ee_r = (-p - NU * (-p - q_yield)) / E
    ee_z = (-q_yield + 2 * NU * p) / E
    ratio = (eps_r - ee_r) / (eps_z - ee_z)
    assert ratio == pytest.approx((0.5 + b / s3) / (b / s3 - 1), rel=1e-8)
    assert h["newton_iterations"][-1] <= 3


BILINEAR = {"form": "ep", "kn": 1e13, "kt": 1e13, "law": "bilinear", "sigma_c": 1e6, "Gc": 50.0, "beta": 1.0}


@pytest.mark.parametrize("section,key", [
    ({"cohesive": {"where": "all", "integration": "implex", **BILINEAR}},
     r"\[cohesive\] \(cohesive 1\): integration = 'implex' and \[solver\] fallback = 'implex' are 2D only"),
    ({"cohesive": {"where": "all", **BILINEAR}, "solver": {"fallback": "implex"}},
     r"\[cohesive\] \(cohesive 1\): integration = 'implex' and \[solver\] fallback = 'implex' are 2D only"),
    ({"cohesive": {"where": "curves", "curves": ["side"], **BILINEAR}},
     r"\[cohesive\] where = 'curves' is for 2D meshes; this one is 3D"),
    ({"embedded": {"c_p": 1e6, "c_r": 0.0, "phi_p": 0.5, "phi_r": 0.0, "psi_p": 0.1, "alpha_c": 500.0,
                   "alpha_phi": 500.0, "alpha_psi": 500.0}},
     r"\[embedded\]: embedded cracks in a general 3D body need hex8 cells; these are tet4"),
])
def test_what_3d_meshes_do_not_carry_yet_is_refused_by_name(tmp_path, section, key):
    from rockfrac.api import make_case
    from rockfrac.errors import CaseError

    msh = TRIAXIAL / "cylinder.msh"
    case = make_case(mesh={"kind": "gmsh", "file": str(msh)},
                     bulk={"model": "drucker_prager", "E": E, "nu": NU, "beta": 0.6, "b": 0.2, "kappa0": 1e7},
                     stages=[{"name": "s", "displacement": {"bottom": {"z": 0.0}}, "pressure": {"top": 1e6}}],
                     **section)
    with pytest.raises(CaseError, match=key):
        run(case, tmp_path / "o")


def test_tetrahedra_are_written_for_paraview(cylinder, tmp_path):
    import meshio

    from rockfrac.output.vtk import step_fields

    m = cylinder
    u = m.nodes * [1e-3, -2e-3, 5e-4]
    grid = step_fields(m.nodes, m.cells, "tet4", point_data={"displacement": u},
                       bulk_data={"stress": np.ones((len(m.cells), 6))})
    meshio.write(tmp_path / "t.vtu", grid.to_meshio())
    back = meshio.read(tmp_path / "t.vtu")
    assert [c.type for c in back.cells] == ["tetra"]
    np.testing.assert_array_equal(back.cells[0].data, m.cells)
    np.testing.assert_allclose(back.point_data["displacement"], u)


@pytest.fixture(scope="module", params=["ep", "rp"])
def jointed(tmp_path_factory, request):
    """The jointed triaxial example as given (EP), and with its joint rigid-plastic (RP), each shortened
    in 30 axial steps instead of the example's 60 (the same 0.6 mm: the joint activates at the end of
    the 6th, shortened to land on it, and slides through the 25 after it)."""
    import tomllib

    from rockfrac.case.schema import parse_case

    d = tomllib.loads((TRIAXIAL / "joint.toml").read_text())
    d["mesh"]["file"] = str(TRIAXIAL / d["mesh"]["file"])
    d["stages"][1]["steps"] = 30
    if request.param == "rp":
        d["cohesive"].update(form="rp", augmentation=1e15)
        del d["cohesive"]["kn"], d["cohesive"]["kt"]
    case = parse_case(d, "joint.toml")
    out = tmp_path_factory.mktemp("joint")
    return case, run(case, out), out


def test_triaxial_joint_slips_at_the_closed_form_and_slides_down_the_dip(jointed):
    """examples/rock_tests/triaxial/joint.toml: homogeneous stress, so the joint (dip 55 deg) carries
    sigma . n at every point; it activates, and then slides at every step, where the law's yield
    function F(T) = 0 with T from the axial stress (with the points' current strengths)."""
    from scipy.optimize import brentq

    from rockfrac.output.csvout import read_csv

    case, r, out = jointed
    h, mesh = r.history, r.built.mesh
    p = 5e6
    dip = math.radians(55.0)
    s, c = math.sin(dip), math.cos(dip)
    area = np.linalg.norm(face_normals(mesh.nodes, mesh.face_sets["bottom"]), axis=1).sum()
    sigma_a = np.asarray(h["R_bottom_z"]) / area
    pts = read_csv(out / "points.csv")
    steps = np.asarray(pts["step"])
    n_pts = int(np.sum(steps == 1))
    assert n_pts > 40

    def axial_at_yield(chi, coh, tphi):
        def f(sa):
            tau, tn = (sa - p) * s * c, -(p * s * s + sa * c * c)
            return math.sqrt(tau**2 + (coh - chi * tphi) ** 2) - (coh - tn * tphi)
        return brentq(f, p, 1e9, xtol=1e-6, rtol=1e-15)

    sec = case.cohesive_sets[0]
    peak = axial_at_yield(sec.chi_p, sec.c_p, math.tan(sec.phi_p))
    assert peak == pytest.approx(26.77e6, rel=2e-3)
    plastic = np.asarray(h["n_plastic"]) > 0
    first = int(np.argmax(plastic))
    # the activation is located: the step before the first plastic one ends on the surface
    assert sigma_a[first - 1] == pytest.approx(peak, rel=1e-9)
    assert sigma_a.max() == pytest.approx(peak, rel=1e-9)
    assert np.all(np.asarray(h["n_plastic"])[plastic] == n_pts)
    for k in np.flatnonzero(plastic)[::5]:
        row = steps == h["step"][k]
        chi, coh, tphi = (np.asarray(pts[q])[row] for q in ("chi", "c", "tan_phi"))
        assert np.ptp(coh) <= 1e-9 * sec.c_p and np.ptp(chi) <= 1e-9 * sec.chi_p  # uniform
        assert sigma_a[k] == pytest.approx(axial_at_yield(chi[0], coh[0], tphi[0]), rel=1e-9)
    assert sigma_a[-1] < 0.9 * peak
    residual = p * (s * c + s * s * math.tan(sec.phi_r)) / (s * c - c * c * math.tan(sec.phi_r))
    assert residual == pytest.approx(18.97e6, rel=1e-3) and sigma_a[-1] > residual
    last = steps == h["step"][-1]
    along_strike = np.abs(np.asarray(pts["jump_p_t1"])[last])
    down_dip = np.abs(np.asarray(pts["jump_p_t2"])[last])
    assert down_dip.min() > 1e-5 and along_strike.max() <= 1e-9 * down_dip.min()
    np.testing.assert_allclose(np.abs(np.asarray(pts["n_z"])[last]), c, rtol=1e-12)
    assert abs(h["energy_error"][-1]) <= 1e-8 * h["W_external"][-1]


def test_3d_crack_map_draws_the_yielded_joint(jointed, tmp_path):
    from rockfrac.output.crack_map import save_crack_map
    from rockfrac.output.fields import step_output

    _, r, _ = jointed
    fields = step_output(r.built, r.u)
    cracks = save_crack_map(tmp_path / "map.png", fields, 100.0, view="3d")
    assert (tmp_path / "map.png").stat().st_size > 10_000
    joint = r.built.mesh.interfaces.shape[0]
    assert cracks.opening.size == joint and joint > 40  # every joint face has slid
    z = cracks.segments[:, 0, 2]
    x = cracks.segments[:, 0, 0]
    dip = math.radians(55.0)
    # the centres lie on the (deformed) joint plane z = H/2 - x tan(dip), to the magnified slip
    assert np.abs(z - (0.05 - x * math.tan(dip))).max() < 0.01


@pytest.mark.parametrize("element", ["hex8", "tet4"])
def test_drucker_prager_box_in_general_3d_yields_at_the_closed_form(tmp_path, element):
    """A Drucker-Prager box of either 3D cell, held in y on both faces (eps_yy = 0), a pressure p on
    the x faces, then shortened along z: every Gauss point carries the same stress, with sigma_x =
    -p, and ends on the cone F = 0 (its three unequal principal stresses), the whole body plastic."""
    from rockfrac.api import make_case

    box = rt.box(tmp_path / "b.msh", (1.0, 1.0, 2.0), (2, 2, 3), element=element)
    beta, b, k0, p = 0.5, 0.1, 5e6, 2e6
    case = make_case(mesh={"kind": "gmsh", "file": str(box)},
                     bulk={"model": "drucker_prager", "E": E, "nu": NU, "beta": beta, "b": b, "kappa0": k0},
                     stages=[{"name": "confine", "displacement": {"left": {"x": 0.0}, "front": {"y": 0.0},
                                                                 "bottom": {"z": 0.0}, "back": {"y": 0.0}},
                              "pressure": {"right": p}},
                             {"name": "axial", "steps": 20, "displacement": {"top": {"z": -2e-3}}}],
                     output={"picture": False})
    r = run(case, tmp_path / "o")
    assert r.history["bulk_plastic"][-1] == 1.0
    s = r.cell_stress()
    sx, sy, sz = s[0, 0], s[0, 1], s[0, 2]
    np.testing.assert_allclose(s, np.broadcast_to(s[0], s.shape), atol=1e-7 * abs(sz))  # homogeneous
    assert sx == pytest.approx(-p, rel=1e-9)
    # on the cone: sqrt(3/2) |dev sigma| + sqrt(3) (beta p_mean - kappa0) = 0
    mean = (sx + sy + sz) / 3
    dev = np.array([sx - mean, sy - mean, sz - mean])
    f = math.sqrt(1.5) * np.linalg.norm(dev) + math.sqrt(3) * (beta * mean - k0)
    assert abs(f) <= 1e-9 * k0
    # plane strain in y (held front and back): eps_yy = 0, so the flow keeps sigma_y between
    assert sz < sy < 0 and sz < -p


def test_3d_interfaces_are_written_for_paraview_with_their_jumps(jointed, tmp_path):
    """The jointed cylinder's step fields: tetrahedra, then the joint as zero-thickness wedges whose
    cell data carry the (t1, t2, n) jump and traction, read back by meshio."""
    import meshio

    from rockfrac.output.fields import step_output

    _, r, _ = jointed
    grid = step_output(r.built, r.u)
    meshio.write(tmp_path / "j.vtu", grid.to_meshio())
    back = meshio.read(tmp_path / "j.vtu")
    kinds = [c.type for c in back.cells]
    assert kinds == ["tetra", "wedge"]
    n_if = r.built.mesh.interfaces.shape[0]
    jump = back.cell_data["jump"][1]
    traction = back.cell_data["traction"][1]
    assert jump.shape == (n_if, 3) and traction.shape == (n_if, 3)
    assert np.all(np.abs(jump[:, 1]) > 10 * np.abs(jump[:, 0]))  # slid down the dip (t2), not along the strike
    np.testing.assert_array_equal(back.cells[1].data, r.built.mesh.interfaces)
