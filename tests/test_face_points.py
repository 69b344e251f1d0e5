"""[cohesive] points = 'faces' (rockfrac.elements.cse_facets, 3D): one point per interface face on its
mean jump, with moments on the face's relative rotations (bending on its normal jumps' zero-mean part,
capped at the tension cap; torsion about its normal, elastic)."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from conftest import check_cohesive_tangent, check_uniform_tractions_3d

from rockfrac.api import make_case, run
from rockfrac.case.build import build
from rockfrac.elements.cse_facets import FacetEP, FacetRP, facet_points
from rockfrac.fem.reference import QUAD4
from rockfrac.mesh import rock_tests as rt
from rockfrac.mesh.interfaces import tied_nodes
from rockfrac.output.csvout import read_csv
from rockfrac.studies import table1

SIGMA = np.diag([-1.0e6, -5.0e5, -2.0e6])  # the patch test's uniform stress [Pa]
POINTS = "faces"
STRONG = {"where": "all", "law": "bilinear", "sigma_c": 1e9, "Gc": 1e3, "beta": 1.0, "points": "faces"}


@pytest.fixture(scope="module", params=["tet4", "hex8"])
def box(tmp_path_factory, request):
    """A unit box of 2 x 2 x 2 cells (tetrahedra: each hexahedron split by Gmsh), and its element."""
    path = rt.box(tmp_path_factory.mktemp("box") / "box.msh", (1.0, 1.0, 1.0), (2, 2, 2), element=request.param)
    return path, request.param


def patch(path, cohesive: dict | None = None):
    """The box on rollers (bottom, left, front), pressed on the other faces: the uniform stress SIGMA."""
    stages = [{"name": "load", "displacement": {"bottom": {"z": 0.0}, "left": {"x": 0.0}, "front": {"y": 0.0}},
               "pressure": {"top": 2e6, "right": 1e6, "back": 5e5}}]
    extra = {"cohesive": cohesive} if cohesive is not None else {}
    return make_case(mesh={"kind": "gmsh", "file": str(path)}, bulk={"E": 2e10, "nu": 0.25}, stages=stages,
                     output={"picture": False}, **extra)


def test_rp_faces_on_every_face_held_shut_give_the_unsplit_solution(box, tmp_path):
    """The patch test: RP face points on every internal face (tetrahedra: up to 8 faces round an edge),
    too strong to yield, under a uniform stress: the unsplit displacements, no jump, and each face's
    traction sigma . n, its shear included (the tetrahedra's oblique faces)."""
    path, element = box
    plain = run(patch(path), tmp_path / "plain")
    split = run(patch(path, dict(STRONG, form="rp", augmentation=1e13)), tmp_path / "split")
    group = split.built.cohesives[0]
    assert isinstance(group, FacetRP)
    rep = tied_nodes(split.built.mesh)
    u, u0 = split.displacement(), plain.displacement()
    assert np.abs(u - u0[rep]).max() <= 1e-10 * np.abs(u0).max()
    shear = check_uniform_tractions_3d(tmp_path / "split" / "points.csv", SIGMA, 2e6)
    if element == "tet4":  # oblique faces, whose shear the multipliers carry
        assert shear.max() > 1e5
    else:
        assert group.points.n == 12 and shear.max() < 1e-9  # the cubes' 12 axis-aligned internal faces


def _stiffness(path, cohesive: dict, torsion: bool = True):
    """The EP model's free-dof tangent at rest (the box fixed on its base), with or without the torsion."""
    built = build(make_case(mesh={"kind": "gmsh", "file": str(path)}, bulk={"E": 2e10, "nu": 0.25}, cohesive=cohesive,
                            stages=[{"name": "p", "displacement": {"bottom": {"x": 0.0, "y": 0.0, "z": 0.0}},
                                     "pressure": {"top": 1e6}}]))
    model = built.model
    model.set_dirichlet(built.stages[0].dirichlet)
    if not torsion:
        built.cohesives[0].torsion_stiffness = 0.0
    model.begin_step()
    z = np.zeros(model.n_dofs)
    a = sp.csr_matrix(model.assemble(z, z, z).matrix)
    free = np.setdiff1d(np.arange(model.n_dofs), built.stages[0].dirichlet)
    return a[free][:, free].toarray()


def test_the_torsion_removes_the_tetrahedra_mechanism(tmp_path):
    """Face points hold a face's mean jump and its bending only: two tetrahedra may still turn about their
    common face's normal, and round an edge of 6-8 faces such turns close into a mechanism (a zero
    eigenvalue of the tangent). With the torsion the tangent is definite."""
    path = rt.box(tmp_path / "box.msh", (1.0, 1.0, 1.0), (2, 2, 2), element="tet4")
    coh = dict(table1.CSE_LAW, form="ep", where="all", points="faces", kn=1e13, kt=1e13)
    low = []
    for torsion in (True, False):
        eig = np.linalg.eigvalsh(_stiffness(path, coh, torsion))
        low.append(eig[0] / eig[-1])
    assert low[0] > 1e-7
    assert low[1] < 1e-14


def _shape_by_gauss(x: np.ndarray, n_gauss: int = 6):
    """Points (q, 3), weights dA (q,) and shape values (q, m) of a face (m = 3 or 4 corners x) by a
    tensor Gauss rule (a triangle as a collapsed quadrilateral)."""
    s, w = np.polynomial.legendre.leggauss(n_gauss)
    xi, eta = np.meshgrid(s, s, indexing="ij")
    ww = np.outer(w, w).ravel()
    xi, eta = xi.ravel(), eta.ravel()
    if x.shape[0] == 4:
        shape = QUAD4.shape(np.stack([xi, eta], axis=1))
        dn = QUAD4.shape_gradients(np.stack([xi, eta], axis=1))
        jac = np.einsum("qa,ai->qi", dn[:, :, 0], x), np.einsum("qa,ai->qi", dn[:, :, 1], x)
        da = np.linalg.norm(np.cross(*jac), axis=1) * ww
    else:  # (r, s) = ((1 + xi) / 2, (1 - r)(1 + eta) / 2) on the unit triangle
        r = 0.5 * (1 + xi)
        t = 0.5 * (1 - r) * (1 + eta)
        shape = np.stack([1 - r - t, r, t], axis=1)
        da = np.linalg.norm(np.cross(x[1] - x[0], x[2] - x[0])) * 0.25 * (1 - r) * ww
    return shape @ x, da, shape


@pytest.mark.parametrize("corners", [
    [[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [1.5, 1.0, 0.0], [0.2, 1.3, 0.0]],  # a trapezoid-like quadrilateral
    [[0.0, 0.0, 0.0], [1.0, 0.2, 0.3], [0.3, 1.1, -0.2]],  # an oblique triangle
], ids=["quad", "tri"])
def test_face_shapes_against_gauss_integrals(corners):
    """facet_points' shares, centroid, bending matrix and torsion against a 6 x 6 Gauss rule: the mean
    jump's shares w_a / A, the bending energy of a normal jump field = k/2 int (g - mean g)^2 dA, and a
    rigid rotation about the normal by theta giving the twist theta and the energy k/2 I theta^2."""
    x = np.asarray(corners)
    m = x.shape[0]
    nodes = np.concatenate([x, x])  # minus copies 0..m-1, plus copies m..2m-1
    cells = np.arange(2 * m)[None, :]
    pts, shape = facet_points(nodes, cells)
    xq, da, nq = _shape_by_gauss(x)
    area = da.sum()
    assert pts.weight[0] == pytest.approx(area, rel=1e-12)
    np.testing.assert_allclose(shape.share[0], nq.T @ da / area, rtol=1e-12)
    centre = xq.T @ da / area
    np.testing.assert_allclose(pts.x[0], centre, rtol=1e-12, atol=1e-14)
    n = pts.frame[0, 2]
    assert abs(n @ (x[1] - x[0])) < 1e-12 and abs(n @ (x[2] - x[0])) < 1e-12
    g = np.array([0.3, -1.0, 0.7, 0.4][:m])
    field = nq @ g
    mean = field @ da / area
    assert 0.5 * g @ shape.bending[0] @ g == pytest.approx(0.5 * np.sum((field - mean) ** 2 * da), rel=1e-12)
    arm = np.cross(n, xq - centre)
    assert shape.polar is not None and shape.torsion is not None
    assert shape.polar[0] == pytest.approx(np.sum(np.einsum("qi,qi->q", arm, arm) * da), rel=1e-12)
    theta = 1e-3
    jump = theta * np.cross(n, x - centre)  # at the corners
    assert np.einsum("ai,ai->", shape.torsion[0], jump) / shape.polar[0] == pytest.approx(theta, rel=1e-12)


@pytest.mark.parametrize("form", ["ep", "rp"])
def test_face_points_tangent_is_the_derivative_of_their_forces(tmp_path, form):
    """The consistent tangent of face points on every face of a tetrahedral box, moments included,
    against central differences of the internal forces, at a state where some points are plastic and
    others are not, and some faces' bending is on its cap (corner tractions at the tensile strength,
    radially returned) and others' is not."""
    path = rt.box(tmp_path / "box.msh", (0.02, 0.02, 0.02), (2, 2, 2), element="tet4")
    law = dict(table1.CSE_LAW, form=form, where="all", points=POINTS,
               **({"kn": 1e13, "kt": 1e13} if form == "ep" else {"augmentation": 1e13}))
    built = build(make_case(mesh={"kind": "gmsh", "file": str(path)}, bulk={"E": 1.5e7, "nu": 0.3}, cohesive=law,
                            stages=[{"name": "p", "displacement": {"bottom": {"x": 0.0, "y": 0.0, "z": 0.0}},
                                     "pressure": {"top": 1e4}}]))
    model = built.model
    model.set_dirichlet(built.stages[0].dirichlet)
    group = built.cohesives[0]
    assert isinstance(group, FacetRP if form == "rp" else FacetEP)
    # steps of 1e-6: the hyperbola's apex is curved on the scale of 1e-10 m (the error falls as h^2)
    u = check_cohesive_tangent(model, group, seed=5, step=1e-6)
    assert group.moment_energy(u) > 0.0
    assert 0 < np.count_nonzero(group.capped) < group.points.n


def sheared_column(path, form: str) -> dict:
    """A 20 x 20 x 40 mm column of 2 x 2 x 4 hexahedra, surfaces of the paper's law (G_f of 20 and 40
    J/m^2) on every internal face, confined at 20 kPa, its top sheared by 0.8 mm and pressed by 0.1 mm in
    8 load steps, viscous (eta = 2.5e-5; EP's kn = kt = RP's augmentation = 2e12 Pa/m)."""
    law = dict(table1.CSE_LAW, GfI=20.0, GfII=40.0, form=form, where="all", points="faces", viscosity=2.5e-5,
               **({"kn": 2e12, "kt": 2e12} if form == "ep" else {"augmentation": 2e12}))
    return make_case(mesh={"kind": "gmsh", "file": str(path)}, bulk={"E": 1.5e7, "nu": 0.3}, cohesive=law,
                     stages=[{"name": "shear", "steps": 8, "control": "load",
                              "displacement": {"bottom": {"x": 0.0, "y": 0.0, "z": 0.0},
                                               "top": {"x": 8e-4, "y": 0.0, "z": -1e-4}},
                              "pressure": {"left": 2e4, "right": 2e4, "front": 2e4, "back": 2e4}}],
                     output={"picture": False, "points": False, "vtk": False})


def test_rp_face_points_follow_ep_face_points_in_3d(tmp_path):
    """Like for like in 3D: RP and EP face points through the shearing of a column with surfaces on every
    face, far past the first yields. The same shear force and dissipation to 2 %, in steps of the same
    order, and the work is the stored energy (the moments' included) plus the dissipation."""
    path = rt.box(tmp_path / "column.msh", (0.02, 0.02, 0.04), (2, 2, 4), element="hex8")
    ep = run(sheared_column(path, "ep"), tmp_path / "ep")
    rp = run(sheared_column(path, "rp"), tmp_path / "rp")
    assert ep.completed and rp.completed, rp.message
    h_ep, h_rp = ep.history, rp.history
    assert h_ep["n_plastic"][-1] >= 8 and h_ep["D_dissipated"][-1] > 0.4 * h_ep["W_external"][-1]
    assert h_rp["R_top_x"][-1] == pytest.approx(h_ep["R_top_x"][-1], rel=0.02)
    assert h_rp["D_dissipated"][-1] == pytest.approx(h_ep["D_dissipated"][-1], rel=0.02)
    assert rp.summary.result.steps <= 2 * ep.summary.result.steps
    for h in (h_ep, h_rp):
        assert abs(h["energy_error"][-1]) <= 1e-9 * h["W_external"][-1]
