"""Nodal embedded cracks in a general 3D body (issues 15 and 16): tetrahedra and hexahedra cut by planes.

- The 3D law (isotropic in the crack's plane): its tangent against central differences in the three
  local directions, objectivity (a trial turned in the plane gives the turned traction), and the 2D
  law where T_t2 = 0.
- A tetrahedron and a hexahedron cut by a plane: each side's volume, the crack polygon's area.
- The patch test in 3D: a uniform stress and a uniform jump across a plane through a box of
  tetrahedra or hexahedra leave no residual (the side pressure split at the crossed faces).
- The tangent of a model with cut tetrahedra against central differences of its residual.
- An inclined plane given across a prism of tetrahedra (the cells the elemental EDE refuses: its
  constant jump, misaligned with the plane in most tetrahedra, raises friction as it slides) or of
  hexahedra: after full softening the axial force is the confinement times the section within
  0.5 %, the slide rigid, the energy balanced.
"""

import math

import numpy as np
import pytest

from rockfrac.case.build import build
from rockfrac.case.schema import parse_case
from rockfrac.fem.planes import EDGES, plane_polygons, polygon_areas
from rockfrac.fem.cut_cell import cut_cell_3d
from rockfrac.fem.reference import HEX8, TET4
from rockfrac.laws import embedded_penalty as EP
from rockfrac.laws.mohr_coulomb_softening import EmbeddedLaw
from rockfrac.mesh import rock_tests as rt
from rockfrac.output.csvout import read_csv
from rockfrac.runner import run_case
from rockfrac.solve.stepping import _EnrichedLoads
from test_ede_3d import ANGLE, DP, H, P, W, plane_case

LAW = EmbeddedLaw(c_r=0.0, phi_p=0.5236, phi_r=0.0, psi_p=0.087, alpha_c=5e3, alpha_phi=5e3, alpha_psi=5e3)
PARAMS = LAW.as_array(c_p=0.0)
K = 1e10
OFFSET = 0.0011


def update(j, st):
    return EP.crack_point_update_3d(np.asarray(j, dtype=float), st, PARAMS, K, K)


def test_3d_law_tangent_objectivity_and_2d_reduction():
    """Over 400 random states and jumps the tangent is the derivative of the traction (central
    differences, beyond their round-off); a trial turned by any angle in the crack's plane gives the
    traction turned by it (1e-9); with no t2 component the traction is the 2D law's (1e-9)."""
    rng = np.random.default_rng(5)
    for _ in range(400):
        st = EP.initial_state_3d(np.array([rng.uniform(-1e4, 1e4), rng.uniform(-1e4, 1e4),
                                           rng.uniform(-3e4, 1e4)]), rng.uniform(1e3, 1e4))
        st[EP.C3_GAMMA] = rng.choice([0.0, 1e-5, 1e-4])
        st[EP.C3_JP:EP.C3_JP + 3] = rng.normal(size=3) * 1e-6
        j = rng.normal(size=3) * 10 ** rng.uniform(-9, -4)
        status, new, tr, d = update(j, st)
        assert status == EP.ST_OK
        h = 1e-6 * np.abs(j).max()
        fd = np.zeros((3, 3))
        for k in range(3):
            e = np.zeros(3)
            e[k] = h
            fd[:, k] = (update(j + e, st)[2] - update(j - e, st)[2]) / (2 * h)
        scale = max(1.0, st[EP.C3_CP], K * np.abs(j - st[EP.C3_JP:EP.C3_JP + 3]).max())
        assert np.abs(fd - d).max() <= 1e-5 * np.abs(d).max() + 1e-11 * scale / h
        a = rng.uniform(0, 2 * math.pi)
        rot = np.array([[math.cos(a), -math.sin(a), 0.0], [math.sin(a), math.cos(a), 0.0], [0.0, 0.0, 1.0]])
        turned = st.copy()
        for slot in (EP.C3_T0, EP.C3_JP, EP.C3_T, EP.C3_J):
            turned[slot:slot + 3] = rot @ st[slot:slot + 3]
        np.testing.assert_allclose(update(rot @ j, turned)[2], rot @ tr, rtol=1e-9, atol=1e-9 * scale)
    st2, st3 = EP.initial_state(-3e3, -2e4, 5e3), EP.initial_state_3d(np.array([-3e3, 0.0, -2e4]), 5e3)
    for j_t in np.linspace(0.0, -2e-4, 41)[1:]:
        _, st2, t2, _ = EP.crack_point_update(j_t, 1e-6, st2, PARAMS, K, K)
        _, st3, t3, _ = update((j_t, 0.0, 1e-6), st3)
        assert t3[1] == 0.0
        np.testing.assert_allclose(t3[[0, 2]], t2, rtol=1e-9)


@pytest.mark.parametrize("ref, xe", [
    (TET4, np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])),
    (HEX8, np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]], float)
     * [2.0, 1.5, 1.0]),
])
def test_a_cut_3d_cell_splits_into_its_two_sides(ref, xe):
    """The sides' weights add up to the cell's volume, each point lies on its side and maps back from
    its reference coordinates; the crack's weights add up to the polygon's area, its points on the
    plane."""
    n = np.array([0.3, -0.4, 0.8]) / np.linalg.norm([0.3, -0.4, 0.8])
    p = xe.mean(axis=0) + 0.05
    c = cut_cell_3d(ref, xe, p, n)
    volume = 1.0 / 6.0 if ref is TET4 else 3.0
    assert c.weights.sum() == pytest.approx(volume, rel=1e-12)
    assert np.all(((c.x - p) @ n > 0) == (c.side == 1))
    np.testing.assert_allclose(ref.shape(c.xi) @ xe, c.x, atol=1e-13)
    poly = plane_polygons(xe[None], EDGES[ref.name], p[None], n[None])[0]
    assert c.crack_weights.sum() == pytest.approx(polygon_areas(poly)[0], rel=1e-12)
    np.testing.assert_allclose((c.crack_x - p) @ n, 0.0, atol=1e-14)


def nodal_plane(msh, offset: float = OFFSET) -> dict:
    case = plane_case(msh, offset)
    case["embedded"].update(kinematics="nodal", kn=K, kt=K, tracking="local")
    case["output"] = {"vtk": False, "picture": False, "points": True}
    return case


@pytest.mark.parametrize("element", ["tet4", "hex8"])
def test_patch_test_in_3d(tmp_path, element):
    """The confinement's exact solution (sigma_xx = -p, eps_yy = eps_zz = 0) with a uniform elastic
    jump K^-1 sigma n across the plane and the upper side translated by it: the residual vanishes
    (1e-12 of the nodal forces), the side pressure split at the faces the plane crosses."""
    msh = rt.box(tmp_path / "box.msh", (W, W, H), (4, 1, 8), element=element)
    built = build(parse_case(nodal_plane(msh)))
    model, stage = built.model, built.program.stages[0]
    _EnrichedLoads(model, built.program.stages)()
    g = built.embeddeds[0]
    registry = g.registry
    registry.refresh()
    E, nu = DP["E"], DP["nu"]
    s_t = nu / (1 - nu) * -P
    sigma = np.diag([-P, s_t, s_t])
    e_xx = -P * (1 + nu) * (1 - 2 * nu) / ((1 - nu) * E)
    n = np.array([-math.sin(ANGLE), 0.0, math.cos(ANGLE)])
    frame = g.cc_frame[0]
    jump = frame.T @ ((frame @ (sigma @ n)) / K)
    x = built.mesh.nodes
    above = (x - np.array([W / 2, W / 2, H / 2 + OFFSET])) @ n > 0
    u = np.zeros(model.n_dofs)
    for a in range(3):
        u[a:3 * x.shape[0]:3] = above * jump[a]
    u[0:3 * x.shape[0]:3] += e_xx * x[:, 0]
    assert registry.enriched.sum() > 0 and registry.crack_count() == 1
    for i in np.flatnonzero(registry.enriched):
        u[registry.offset + 3 * i: registry.offset + 3 * i + 3] = jump
    model.begin_step()
    residual = model.assemble(u, u, stage.f_ext_end).residual
    residual[model.dirichlet] = 0.0
    assert np.abs(residual).max() <= 1e-12 * P * (W / 4) ** 2


def test_3d_assembled_tangent_against_central_differences(tmp_path):
    """Cut tetrahedra with sliding and opening crack points: the tangent is the residual's derivative."""
    msh = rt.box(tmp_path / "box.msh", (W, W, H), (2, 1, 4), element="tet4")
    built = build(parse_case(nodal_plane(msh)))
    model = built.model
    rng = np.random.default_rng(0)
    u = rng.normal(size=model.n_dofs) * 2e-6
    zero = np.zeros(model.n_dofs)
    model.begin_step()
    a = model.assemble(u, zero, zero).matrix.toarray()
    registry = built.embeddeds[0].registry
    enriched = registry.offset + np.flatnonzero(np.repeat(registry.enriched, 3))
    cols = np.concatenate([rng.choice(registry.offset, 20, replace=False), enriched[:40]])
    h = 1e-10
    for j in cols:
        e = np.zeros(model.n_dofs)
        e[j] = h
        fd = (model.assemble(u + e, zero, zero).residual - model.assemble(u - e, zero, zero).residual) / (2 * h)
        assert np.abs(fd - a[:, j]).max() <= 1e-6 * np.abs(a).max()
    modes = built.embeddeds[0].cc_cp_trial[..., EP.C3_MODE]
    assert (modes > 0).any()


@pytest.mark.parametrize("element", ["tet4", "hex8"])
def test_an_inclined_plane_across_a_prism_slides_to_the_closed_form(tmp_path, element):
    """After full softening the axial force is the confinement times the section within 0.5 % (the
    elemental EDE refuses tetrahedra), the strengths are gone, the shear tractions too, every crack
    point has slid the same (one rigid sliding, within 0.5 %), and the energy balance closes."""
    msh = rt.box(tmp_path / "prism.msh", (W, W, H), (6, 2, 12), element=element)
    case = nodal_plane(msh)
    case["stages"][1]["path_increment"] = 1e-4  # the slide after the peak in a fifth of the steps
    s = run_case(parse_case(case), tmp_path / "o")
    h = read_csv(tmp_path / "o" / "history.csv")
    assert s.result.completed
    force = -h["R_top_z"]
    assert force.max() > 3 * P * W * W
    assert force[-1] == pytest.approx(P * W * W, rel=5e-3)
    g = s.built.embeddeds[0]
    cp = g.cc_cp[g.cc_wk > 0]
    assert np.abs(cp[:, EP.C3_T:EP.C3_T + 2]).max() < 1e-3 * P
    slip = np.linalg.norm(cp[:, EP.C3_JP:EP.C3_JP + 2], axis=1)
    assert np.ptp(slip) < 5e-3 * slip.max()
    assert np.abs(h["energy_error"]).max() < 1e-9 * h["D_dissipated"][-1]


# --- a generated block of tetrahedra -------------------------------------------------------------


def test_a_block_of_tetrahedra_is_the_hexahedra_split_conformingly():
    """[mesh] kind = "block", element = "tet4": every hexahedron of the grid becomes six right-handed
    tetrahedra of the same volume, conforming (the boundary is the grid's boundary quads, two triangles
    each), the inclusion's cells follow, and the face sets are outward triangles on x = 0 and x = W."""
    from rockfrac.mesh.specimen import hex_specimen, split_into_tets
    from rockfrac.mesh.topology import boundary_faces

    hexes = hex_specimen(0.04, 0.08, 0.01, 3, 4, 2, inclusion=(0.0, 0.0, 0.02, 0.03))
    tets = split_into_tets(hexes)
    assert tets.check() == [] and tets.cells.shape == (6 * 24, 4)
    x = tets.nodes[tets.cells]
    volume = np.einsum("ki,ki->k", np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]), x[:, 3] - x[:, 0]) / 6
    assert volume.min() > 0 and volume.sum() == pytest.approx(0.04 * 0.08 * 0.01, rel=1e-12)
    assert boundary_faces(tets).shape[0] == 2 * boundary_faces(hexes).shape[0]
    for name, v in hexes.regions.items():
        np.testing.assert_array_equal(np.sort(tets.regions[name] // 6), np.repeat(v, 6))
    for name, at, sign in (("left", 0.0, -1.0), ("right", 0.04, 1.0)):
        f = tets.nodes[tets.face_sets[name]]
        np.testing.assert_allclose(f[..., 0], at, atol=1e-15)
        n = np.cross(f[:, 1] - f[:, 0], f[:, 2] - f[:, 0])
        assert np.all(sign * n[:, 0] > 0) and 0.5 * n[:, 0].__abs__().sum() == pytest.approx(0.08 * 0.01)


# --- a band grown through tetrahedra --------------------------------------------------------------


def strengths_3d(s) -> tuple[float, float, float]:
    """The cut cells' crack points' weighted mean cohesion [Pa] and tan phi, and the largest cohesion
    left [Pa] (rockfrac.laws.mohr_coulomb_softening, at each point's gamma and c_p)."""
    from rockfrac.laws.mohr_coulomb_softening import strengths

    g = s.built.embeddeds[0]
    c, tphi, w = [], [], []
    for row, weights in zip(g.cc_cp, g.cc_wk):
        for point, weight in zip(row, weights):
            if weight > 0:
                ck, tk = strengths(point[EP.C3_GAMMA], point[EP.C3_CP], g.surface_params)[:2]
                c.append(ck)
                tphi.append(tk)
                w.append(weight)
    w = np.asarray(w)
    return float(np.dot(c, w) / w.sum()), float(np.dot(tphi, w) / w.sum()), float(max(c))


def test_a_band_grown_through_tetrahedra_is_one_plane_and_softens_to_the_closed_form(tmp_path):
    """examples/embedded_3d/band_tets.toml on an 8 x 16 x 1 grid (768 tetrahedra), to 3 mm in load
    steps of 0.02 mm and path increments of 1e-4 (five times the example's: the holds after cuts, not
    the increment, set how far the band runs, so it cuts the same cells): the band starts in the weak
    seed and grows cell by cell (local tracking) as one plane -- every cut cell's normal and offset
    the same to round-off -- at the bifurcation angle (56 +- 2 deg from horizontal, within 1.5 deg
    of the loading plane: the tetrahedra are not symmetric through the thickness), through
    the thickness and from the left edge to the right one; after full softening the force per unit
    thickness is the Mohr-Coulomb closed form of the band at its strengths left (p W with none)
    within 1 %, and the energy balance closes. The elemental EDE refuses tetrahedra."""
    import tomllib
    from pathlib import Path

    path = Path(__file__).resolve().parents[1] / "examples" / "embedded_3d" / "band_tets.toml"
    case = tomllib.loads(path.read_text())
    case["mesh"].update(nx=8, ny=16, nz=1)
    case["loading"].update(axial_displacement=3e-3, axial_steps=150, path_increment=1e-4)
    case["output"] = {"vtk": False, "picture": False}
    s = run_case(parse_case(case, str(path)), tmp_path / "o")
    h = read_csv(tmp_path / "o" / "history.csv")
    assert s.result.completed
    g = s.built.embeddeds[0]
    cut = g.localized()
    assert cut.size > 40
    normals = g.e_state[cut, 1:4]
    normals *= np.sign(normals[:, 1:2])
    np.testing.assert_allclose(normals, np.broadcast_to(normals[0], normals.shape), atol=1e-9)
    assert abs(normals[0, 2]) < math.sin(math.radians(1.5))  # near the loading plane (the split is not symmetric in z)
    offsets = np.einsum("ki,ki->k", g.anchor[cut], normals)
    assert np.ptp(offsets) < 1e-12
    angle = math.degrees(math.atan2(abs(normals[0, 0]), abs(normals[0, 1])))
    assert angle == pytest.approx(56.0, abs=2.0)
    x = g.x[cut].reshape(-1, 3)
    assert x[:, 0].min() == 0.0 and x[:, 0].max() == pytest.approx(W) and np.ptp(x[:, 2]) == pytest.approx(0.01)
    c, tphi, c_left = strengths_3d(s)
    assert c_left < 10.0
    th = math.radians(90.0 - angle)
    sn, co = math.sin(th), math.cos(th)
    reference = W * (c + P * (sn * co + tphi * co ** 2)) / (sn * co - tphi * sn ** 2)
    assert reference == pytest.approx(P * W, rel=2e-3)
    assert h["F_axial"][-1] == pytest.approx(reference, rel=0.01)
    assert h["F_axial"].max() > 5 * h["F_axial"][-1]
    assert np.abs(h["energy_error"]).max() < 1e-9 * h["D_dissipated"][-1]


@pytest.mark.parametrize("element", ["tet4", "hex8"])
def test_in_situ_stress_with_a_plane_across_is_an_equilibrium_in_3d(tmp_path, element):
    """A general anisotropic in-situ stress (every shear component) held by its tractions on the whole
    boundary, the inclined plane cut after it is set: u = 0, q = 0 is the exact solution, the
    enriched unknowns' share of the in-situ tractions on the faces the plane crosses included
    (it is not zero, and the residual without it is not)."""
    msh = rt.box(tmp_path / "box.msh", (W, W, H), (4, 1, 8), element=element)
    case = nodal_plane(msh)
    case.pop("loading", None)
    case.pop("stages", None)
    sigma0 = [-P, -1.3 * P, -1.6 * P, 0.1 * P, -0.05 * P, 0.08 * P]  # xx, yy, zz, xy, yz, xz [Pa]
    case["initial"] = {"stress": [{"stress": sigma0}]}
    case["stages"] = [{"name": "hold", "displacement": {"bottom": {"z": 0.0}, "bottom_left": {"x": 0.0},
                                                        "front": {"y": 0.0}}}]
    built = build(parse_case(case))
    model, stage = built.model, built.program.stages[0]
    registry = built.embeddeds[0].registry
    f0 = built.program.f0
    own = f0.copy()
    _EnrichedLoads(model, built.program.stages, f0)()
    share = f0 - own
    assert registry.enriched.sum() > 0 and np.abs(share).max() > 1e-3 * P * (W / 4) ** 2
    u = built.program.u0.copy()
    model.begin_step()
    residual = model.assemble(u, u, f0).residual
    residual[model.dirichlet] = 0.0
    assert np.abs(residual).max() <= 1e-11 * P * (W / 4) ** 2
    without = residual + share
    without[model.dirichlet] = 0.0
    assert np.abs(without).max() > 1e-3 * P * (W / 4) ** 2


def test_the_eight_point_tetrahedron_rule_is_of_degree_three():
    """TET_RULE_3 (a cut hexahedron's sides): positive weights summing to the volume, points inside,
    and every monomial of the barycentric coordinates up to degree 3 integrated exactly
    (int l1^a l2^b l3^c l4^d dV = 3! a! b! c! d! / (a + b + c + d + 3)! V)."""
    import itertools

    from rockfrac.fem.cut_cell import TET_RULE_3

    points, weights = TET_RULE_3
    assert (weights > 0).all() and weights.sum() == pytest.approx(1.0, abs=1e-15)
    assert (points > 0).all() and np.allclose(points.sum(axis=1), 1.0, atol=1e-15)
    for powers in itertools.product(range(4), repeat=4):
        if sum(powers) <= 3:
            exact = 6 * np.prod([math.factorial(k) for k in powers]) / math.factorial(sum(powers) + 3)
            assert weights @ np.prod(points ** np.array(powers), axis=1) == pytest.approx(exact, abs=1e-15)
