"""Nodal embedded cracks (issue 15: bands without stress locking), the pieces apart from whole runs.

- The crack's law (Sect. 4.1 with a penalty and a tension cut-off): tangent against central
  differences in every regime (elastic, sliding, opening, the corner), admissible tractions, the
  closed forms of a pure opening (T_n = c(w)) and of the dilatancy (J_p,n = psi_p / alpha_psi
  (1 - exp(-alpha_psi gamma)) as the slip grows).
- A cell cut by a line: each side's area against the polygon's, points on their side and inside
  the cell, the crack's points on the chord with Simpson's weights.
- The patch test: under a uniform stress and a uniform jump across a crack that cuts a block from
  side to side (the + side translated by the jump), the assembled residual vanishes, on quads and
  triangles, with the confinement on the boundaries the crack crosses split between its sides.
- The assembled tangent against central differences of the residual, with cut cells.
- What is refused by name.
"""

import math

import numpy as np
import pytest

from rockfrac.case.build import build
from rockfrac.case.schema import CaseError, parse_case
from rockfrac.fem.cut_cell import cut_cell, physical_gradients
from rockfrac.fem.reference import QUAD4, TRI3
from rockfrac.laws import embedded_penalty as EP
from rockfrac.laws.mohr_coulomb_softening import EmbeddedLaw, strengths
from rockfrac.runner import run_case
from rockfrac.solve.stepping import _EnrichedLoads

LAW = EmbeddedLaw(c_r=0.0, phi_p=0.5236, phi_r=0.0, psi_p=0.087, alpha_c=5e3, alpha_phi=5e3, alpha_psi=5e3)
PARAMS = LAW.as_array(c_p=0.0)
K = 1e11
W, H, P = 0.04, 0.08, 2e4
DP = {"model": "drucker_prager", "E": 1.5e7, "nu": 0.3, "beta": 0.480385, "b": 0.321597, "H": 43802.9,
      "kappa0": 1e7}  # never yields


def update(j, st):
    return EP.crack_point_update(float(j[0]), float(j[1]), st, PARAMS, K, K)


def surfaces(st_new, tr):
    """(F1, F2): the shear surface and the tension cut-off at the returned traction [Pa]."""
    c, tphi = strengths(st_new[EP.CP_GAMMA], st_new[EP.CP_CP], PARAMS)[:2]
    return abs(tr[0]) + tphi * min(tr[1], 0.0) - c, tr[1] - c


def trials(n, seed=1):
    rng = np.random.default_rng(seed)
    for _ in range(n):
        st = EP.initial_state(rng.uniform(-1e4, 1e4), rng.uniform(-3e4, 1e4), rng.uniform(1e3, 1e4))
        st[EP.CP_GAMMA] = rng.choice([0.0, 1e-5, 1e-4, 1e-3])
        st[EP.CP_JP] = rng.normal() * 1e-6
        st[EP.CP_JP + 1] = abs(rng.normal()) * 1e-6
        yield st, rng.normal(size=2) * 10 ** rng.uniform(-9, -4)


# --- the law ----------------------------------------------------------------------------------

def test_tangent_against_central_differences_in_every_regime():
    """Over 600 random states and jumps the four regimes (elastic 0, sliding 1, opening 2, both 3)
    occur, every return succeeds, the
    traction is admissible and the tangent is the derivative of the traction (central differences,
    steps of 1e-6 of the jump; to 1e-5 beyond the differences' round-off)."""
    modes = set()
    for st, j in trials(600):
        status, new, tr, d = update(j, st)
        assert status == EP.ST_OK
        f1, f2 = surfaces(new, tr)
        scale = max(1.0, st[EP.CP_CP], K * np.abs(j - st[EP.CP_JP:EP.CP_JP + 2]).max())  # the trial's
        assert f1 <= 1e-9 * scale and f2 <= 1e-9 * scale
        modes.add(float(new[EP.CP_MODE]))
        if new[EP.CP_MODE] == 3.0:  # the corner: both surfaces hold
            assert abs(f1) <= 1e-9 * scale and abs(f2) <= 1e-9 * scale
        h = 1e-6 * max(np.abs(j).max(), 1e-8)
        fd = np.zeros((2, 2))
        for k in range(2):
            e = np.zeros(2)
            e[k] = h
            fd[:, k] = (update(j + e, st)[2] - update(j - e, st)[2]) / (2 * h)
        # the returns converge to 1e-12 of the trial traction: the differences' round-off is that / h
        assert np.abs(fd - d).max() <= 1e-5 * np.abs(d).max() + 1e-11 * scale / h
    assert modes >= {0.0, 1.0, 2.0, 3.0}


def test_pure_opening_softens_as_the_cohesion():
    """Opened from a crack at rest: elastic up to T_n = c_p, then T_n = c(w) = c_p exp(-alpha_c w), w
    the plastic opening (gamma = w), whatever the step."""
    c_p = 5e3
    st = EP.initial_state(0.0, 0.0, c_p)
    for j_n in np.linspace(0.0, 4e-4, 81)[1:]:
        status, st, tr, _ = update((0.0, j_n), st)
        assert status == EP.ST_OK
        w = st[EP.CP_JP + 1]
        assert st[EP.CP_GAMMA] == pytest.approx(w, rel=1e-12, abs=1e-18)
        expected = min(K * j_n, c_p * math.exp(-LAW.alpha_c * w))
        assert tr[1] == pytest.approx(expected, rel=1e-9)
        assert tr[0] == 0.0
    assert w == pytest.approx(4e-4 - tr[1] / K, rel=1e-9)


def test_slip_dilates_by_the_integral_of_tan_psi():
    """Slid in small steps under a held normal jump: the dilatant opening J_p,n follows
    int sin(psi) d zeta, psi = psi_p exp(-alpha_psi gamma), gamma = int cos(psi) d zeta (closed form
    within 0.1 % of psi_p / alpha_psi), and the sliding point stays on its surface."""
    st = EP.initial_state(-1.5e4, -2e4, 1.5e4 - math.tan(LAW.phi_p) * 2e4)  # at yield: c_p = |T_t| + tan(phi) T_n
    for j_t in -np.linspace(0.0, 1e-3, 2001)[1:]:
        status, st, tr, _ = update((j_t, 0.0), st)
        assert status == EP.ST_OK
    gamma = st[EP.CP_GAMMA]
    closed = LAW.psi_p / LAW.alpha_psi * (1.0 - math.exp(-LAW.alpha_psi * gamma))  # d J_n / d gamma = tan(psi)
    assert st[EP.CP_JP + 1] == pytest.approx(closed, abs=1e-3 * LAW.psi_p / LAW.alpha_psi)
    f1, _ = surfaces(st, tr)
    assert abs(f1) <= 1e-9 * abs(tr).max()


# --- a cut cell ---------------------------------------------------------------------------------

def shoelace(poly):
    x, y = poly[:, 0], poly[:, 1]
    return 0.5 * abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


@pytest.mark.parametrize("ref, xe, point, angle", [
    (QUAD4, np.array([[0.0, 0.0], [2.0, 0.2], [2.3, 1.7], [-0.1, 1.5]]), (1.0, 0.8), 1.0),
    (QUAD4, np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]), (0.9, 0.9), 2.4),  # a corner cut off
    (TRI3, np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]), (0.3, 0.3), 0.6),
])
def test_a_cut_cell_splits_into_its_two_sides(ref, xe, point, angle):
    """Each side's weights add up to its polygon's area, its points lie on its side inside the cell
    and map back from their reference coordinates; the crack's three points lie on the chord, ends
    on the cell edges, with weights (1, 4, 1)/6 of its length; the side gradients are exact on a
    linear field."""
    n = np.array([-math.sin(angle), math.cos(angle)])
    p = np.array(point)
    c = cut_cell(ref, xe, p, n)
    above = (xe - p) @ n > 0
    ends = c.crack_x[[0, 2]]
    for side, keep in ((1, above), (0, ~above)):
        poly = np.vstack([xe[keep], ends])
        centre = poly.mean(axis=0)
        poly = poly[np.argsort(np.arctan2(*(poly - centre).T[::-1]))]
        assert c.weights[c.side == side].sum() == pytest.approx(shoelace(poly), rel=1e-12)
        assert np.all(((c.x[c.side == side] - p) @ n > 0) == bool(side))
    np.testing.assert_allclose(ref.shape(c.xi) @ xe, c.x, atol=1e-14)
    np.testing.assert_allclose(ref.shape(c.crack_xi) @ xe, c.crack_x, atol=1e-14)
    np.testing.assert_allclose((c.crack_x - p) @ n, 0.0, atol=1e-14)
    length = np.linalg.norm(ends[1] - ends[0])
    np.testing.assert_allclose(c.crack_weights, np.array([1.0, 4.0, 1.0]) * length / 6.0, rtol=1e-14)
    for end, edge in zip(ends, c.crack_edges):
        a, b = xe[edge], xe[(edge + 1) % len(xe)]
        assert abs(np.cross(np.append(b - a, 0), np.append(end - a, 0))[2]) < 1e-14
    g = physical_gradients(ref, xe, c.xi)
    u = 3.0 * xe[:, 0] - 2.0 * xe[:, 1]
    np.testing.assert_allclose(np.einsum("pai,a->pi", g, u), np.broadcast_to([3.0, -2.0], (c.x.shape[0], 2)),
                               atol=1e-12)


# --- the assembled equations ----------------------------------------------------------------------

def crack_case(mesh: dict, angle_deg: float = 56.0, y0: float = 0.01013) -> dict:
    rise = W * math.tan(math.radians(angle_deg))
    regions = ["bulk", "weak"] if mesh.get("kind") == "block" else ["bulk"]
    return {
        "mesh": mesh, "materials": [dict(DP, region=r) for r in regions],
        "embedded": {"c_r": 0.0, "phi_p": 0.5236, "phi_r": 0.0, "psi_p": 0.087, "alpha_c": 5e3, "alpha_phi": 5e3,
                     "alpha_psi": 5e3, "kinematics": "nodal", "kn": K, "kt": K, "tracking": "local",
                     "cracks": [{"points": [[0.0, y0], [W, y0 + rise]], "c_p": 5e3}]},
        "loading": {"confinement": P, "axial_displacement": 2e-3, "axial_steps": 100, "control": "path",
                    "path_increment": 2e-5, "max_steps": 400},
        "output": {"vtk": False},
    }


def block(nx: int, ny: int, element: str = "quad4") -> dict:
    return {"kind": "block", "element": element, "width": W, "height": H, "nx": nx, "ny": ny,
            "inclusion": [0.0, 0.0, W / nx, H / ny]}


@pytest.mark.parametrize("element", ["quad4", "tri3", "gmsh"])
def test_patch_test_uniform_stress_and_uniform_jump(element, tmp_path):
    """The confinement stage's exact solution with a crack from side to side: a uniform plane-strain
    stress (sigma_xx = -p, eps_yy = 0), a uniform elastic jump K^-1 sigma n, the + side translated
    by it. The residual vanishes to round-off (1e-12 of the nodal forces p h), the enriched unknowns'
    share of the side pressure included; on structured quads and triangles and on an unstructured
    Gmsh triangle mesh (its cells cut in no particular order: the crack's pieces are joined where
    they meet)."""
    if element == "gmsh":
        from test_crack_tracking import triangle_block

        case = crack_case({"kind": "gmsh", "file": str(triangle_block(tmp_path / "tri.msh", 0.004))})
        case["materials"] = [dict(case["materials"][0], region=r) for r in ("bulk", "weak")]
    else:
        case = crack_case(block(6, 12, element))
    built = build(parse_case(case))
    model, stage = built.model, built.program.stages[0]
    _EnrichedLoads(model, built.program.stages)()
    groups = built.embeddeds
    registry = groups[0].registry
    E, nu = DP["E"], DP["nu"]
    e_xx = -P * (1 + nu) * (1 - 2 * nu) / ((1 - nu) * E)
    s_yy = nu / (1 - nu) * -P  # plane strain, eps_yy = 0: s_yy = s_zz = nu / (1 - nu) s_xx
    sigma = np.array([[-P, 0.0], [0.0, s_yy]])
    frame = groups[0].cc_frame[0]  # every cell of the straight crack: the same (t, n)
    t, n = frame
    traction = sigma @ n
    jump = (traction @ t) / K * t + (traction @ n) / K * n
    x = built.mesh.nodes[:, :2]
    angle = math.radians(56.0)
    above = (x - np.array([0.0, 0.01013])) @ np.array([-math.sin(angle), math.cos(angle)]) > 0
    u = np.zeros(model.n_dofs)
    u[0:2 * x.shape[0]:2] = e_xx * x[:, 0] + above * jump[0]
    u[1:2 * x.shape[0]:2] = above * jump[1]
    registry.refresh()
    assert registry.enriched.sum() > 0 and registry.crack_count() == 1
    for i in np.flatnonzero(registry.enriched):
        u[registry.offset + 2 * i: registry.offset + 2 * i + 2] = jump
    model.begin_step()
    residual = model.assemble(u, u, stage.f_ext_end).residual
    residual[model.dirichlet] = 0.0
    assert np.abs(residual).max() <= 1e-12 * P * W / 6


def test_assembled_tangent_against_central_differences():
    """With cells cut and crack points sliding, softening and opening (a random state of the
    unknowns), the model's tangent is the derivative of its residual (relative 1e-6)."""
    built = build(parse_case(crack_case(block(6, 12))))
    model = built.model
    rng = np.random.default_rng(0)
    u = rng.normal(size=model.n_dofs) * 2e-6
    model.begin_step()
    zero = np.zeros(model.n_dofs)
    a = model.assemble(u, zero, zero).matrix.toarray()
    registry = built.embeddeds[0].registry
    enriched = registry.offset + np.flatnonzero(np.repeat(registry.enriched, 2))
    cols = np.concatenate([rng.choice(registry.offset, 30, replace=False), enriched])
    h = 1e-10
    modes = np.concatenate([g.cc_cp_trial[..., EP.CP_MODE].ravel() for g in built.embeddeds])
    for j in cols:
        e = np.zeros(model.n_dofs)
        e[j] = h
        fd = (model.assemble(u + e, zero, zero).residual - model.assemble(u - e, zero, zero).residual) / (2 * h)
        assert np.abs(fd - a[:, j]).max() <= 1e-6 * np.abs(a).max()
    model.assemble(u, zero, zero)
    modes = np.concatenate([g.cc_cp_trial[..., EP.CP_MODE].ravel() for g in built.embeddeds])
    assert {1.0}.issubset(set(modes.tolist()))


@pytest.mark.parametrize("change, expected", [
    ({"kn": None}, "kinematics = 'nodal' needs the crack's penalty stiffnesses kn and kt"),
    ({"tracking": "none"}, "kinematics = 'nodal' needs a continuous crack path"),
    ({"kinematics": "elemental"}, "kn and kt are the penalty of kinematics = 'nodal'"),
])
def test_bad_nodal_sections_are_refused(change, expected):
    case = crack_case(block(6, 12))
    case["embedded"].update(change)
    case["embedded"] = {k: v for k, v in case["embedded"].items() if v is not None}
    with pytest.raises(CaseError, match=expected):
        parse_case(case)


def test_in_situ_stress_is_an_equilibrium_with_a_crack_across(tmp_path):
    """An anisotropic in-situ stress (with shear) held by its tractions on the whole outer boundary,
    and a crack given from side to side: the crack is cut after the stress is set, so its points start
    from sigma0 . n and its sides carry sigma0; u = 0 and q = 0 is then the exact solution, the
    enriched unknowns' share of the in-situ tractions included (the crack crosses the loaded left and
    right edges). The residual vanishes to round-off; without that share it would not."""
    case = crack_case(block(6, 12))
    del case["loading"]
    sigma0 = [-P, -1.5 * P, -1.2 * P, 0.15 * P]  # xx, yy, zz, xy [Pa]
    case["initial"] = {"stress": [{"stress": sigma0}]}
    case["stages"] = [{"name": "hold", "displacement": {"bottom": {"y": 0.0}, "bottom_left": {"x": 0.0}}}]
    built = build(parse_case(case))
    model, stage = built.model, built.program.stages[0]
    registry = built.embeddeds[0].registry
    own = stage.f_ext_end.copy()
    _EnrichedLoads(model, built.program.stages)()
    q = registry.offset + np.arange(registry.size)
    share = stage.f_ext_end[q] - own[q]
    assert registry.enriched.sum() > 0 and np.abs(share).max() > 1e-3 * P * W / 6  # the crack meets the loaded edges
    g = built.embeddeds[0]
    n = g.cc_frame[0, 1]
    sig = np.array([[sigma0[0], sigma0[3]], [sigma0[3], sigma0[1]]])
    traction = sig @ n  # the crack's points start from it
    for slot in range(g.cc_cell.size):
        np.testing.assert_allclose(g.cc_sigma[slot, :np.count_nonzero(g.cc_w[slot])][:, [0, 1, 3]],
                                   np.broadcast_to(np.array(sigma0)[[0, 1, 3]],
                                                   (np.count_nonzero(g.cc_w[slot]), 3)), rtol=1e-12)
    t_frame = g.cc_frame[:, 0]
    starts = g.cc_cp[:, 0, EP.CP_T0:EP.CP_T0 + 2]
    np.testing.assert_allclose(starts[:, 0], t_frame @ traction, rtol=1e-9)
    np.testing.assert_allclose(starts[:, 1], n @ traction, rtol=1e-9)
    u = built.program.u0.copy()
    model.begin_step()
    residual = model.assemble(u, u, stage.f_ext_end).residual
    residual[model.dirichlet] = 0.0
    assert np.abs(residual).max() <= 1e-12 * P * W / 6
    residual_without = residual + (stage.f_ext_end - own)
    assert np.abs(residual_without).max() > 1e-3 * P * W / 6
