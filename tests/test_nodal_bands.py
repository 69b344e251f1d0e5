"""Nodal embedded cracks in whole runs (issue 15): bands without stress locking.

- A straight crack given in an elastic rock slides to the closed form (the confinement times the
  width) within 0.5 %, rigidly, on quads and on an unstructured triangle mesh; two parallel cracks
  slide too.
- The oblique band of tests/test_crack_tracking.py, grown by nonlocal tracking in a rock that has
  yielded before it forms, crosses from the left edge to the right one, straight and continuous,
  and after full softening its force is within 2 % of the Mohr-Coulomb closed form of the band's
  strengths left (with none left: p w). The elemental EDE ends this case at 1.76 times it (the
  stress carried along its cut cells crosses them: benchmarks/README.md, "Embedded band tracking").
- Energy: the work of the external forces is the stored energy plus the dissipation, the crack's
  law's own account included.
"""

import math

import numpy as np
import pytest

from rockfrac.case.schema import parse_case
from rockfrac.laws import embedded_penalty as EP
from rockfrac.laws.mohr_coulomb_softening import strengths
from rockfrac.output.csvout import read_csv
from rockfrac.runner import run_case
from test_crack_tracking import W, band_case, chain, triangle_block
from test_nodal_cracks import block, crack_case

P = 2e4
KN = 1e10  # [Pa/m]: the crack's penalty, about E / h on these meshes


def nodal(case: dict, k: float = KN) -> dict:
    case["embedded"].update(kinematics="nodal", kn=k, kt=k)
    return case


def closed_form(s) -> tuple[float, float]:
    """The Mohr-Coulomb force [N/m] that slides the band at its crack points' mean strengths and its
    cells' mean angle (EDE_NOTES; p w with none left), and the largest cohesion left [Pa]."""
    c, tphi, w, angles, c_max = [], [], [], [], 0.0
    for g in s.built.embeddeds:
        law = g.surface_params
        for row, weights, frame in zip(g.cc_cp, g.cc_wk, g.cc_frame):
            for point, weight in zip(row, weights):
                ck, tk = strengths(point[EP.CP_GAMMA], point[EP.CP_CP], law)[:2]
                c.append(ck)
                tphi.append(tk)
                w.append(weight)
                c_max = max(c_max, ck)
            angles.append(math.atan2(abs(frame[0, 1]), abs(frame[0, 0])))
    w = np.array(w)
    cm, tm = float(np.dot(c, w) / w.sum()), float(np.dot(tphi, w) / w.sum())
    th = math.pi / 2 - float(np.mean(angles))  # the normal's angle from the lateral axis
    sn, co = math.sin(th), math.cos(th)
    return W * (cm + P * (sn * co + tm * co ** 2)) / (sn * co - tm * sn ** 2), c_max


def shortened(case: dict) -> dict:
    """A given crack's case stopped at 1.3 mm instead of 2 mm, at the same load step (2e-5 m) and
    path increment: the run is the same up to there, and by then the crack has softened fully (the
    force within 0.5 % of p w from about 1.0 mm on; at 1.3 mm within 0.1 %, the largest shear
    traction 8 Pa). No crack_map.png (about 1.5 s of drawing a run; no test looks at it)."""
    case["loading"].update(axial_displacement=1.3e-3, axial_steps=65)
    case["output"]["picture"] = False
    return case


@pytest.mark.parametrize("mesh", ["quads", "triangles"])
def test_a_given_crack_slides_rigidly_to_the_closed_form(tmp_path, mesh):
    """After full softening the force is p w within 0.5 %, every crack point's shear traction is
    gone and the jump along the crack is one rigid sliding (within 0.5 %)."""
    if mesh == "quads":
        m = block(16, 32)
    else:
        m = {"kind": "gmsh", "file": str(triangle_block(tmp_path / "tri.msh", 0.004))}
    case = crack_case(m)
    shortened(case)
    if mesh == "triangles":
        case["materials"] = [dict(case["materials"][0], region=r) for r in ("bulk", "weak")]
    s = run_case(parse_case(case), tmp_path / "o")
    h = read_csv(tmp_path / "o" / "history.csv")
    assert s.result.completed
    assert h["F_axial"].max() > 3 * P * W
    assert h["F_axial"][-1] == pytest.approx(P * W, rel=5e-3)
    cp = np.concatenate([g.cc_cp.reshape(-1, EP.N_CP) for g in s.built.embeddeds])
    assert np.abs(cp[:, EP.CP_T]).max() < 1e-3 * P
    jt = cp[:, EP.CP_J]
    assert np.ptp(jt) < 5e-3 * np.abs(jt).max()


def test_a_given_crack_through_a_node_across_two_regions_is_one_crack(tmp_path):
    """A crack that starts in the weak region and ends exactly at a node of the right edge: the
    line is moved off the node (by 2e-7 cell sizes) for the cells of both regions alike, so the
    pieces cut in each region meet on the sides between them and join into one crack, which slides
    to p w. (Moved in one region only, the two pieces' traces missed each other by 3e-10 m: two
    cracks, locked where they met, the force ending at 1.6 p w on the 40 x 80 band.)"""
    case = crack_case(dict(block(16, 32), inclusion=[0.0, 0.005, W / 16, 0.02]))  # the first column's weak
    shortened(case)
    case["embedded"]["cracks"] = [{"points": [[0.0, 0.0132], [W, 0.0725]], "c_p": 5e3}]  # y = 72.5 mm: a node
    s = run_case(parse_case(case), tmp_path / "o")
    h = read_csv(tmp_path / "o" / "history.csv")
    registry = next(g for g in s.built.model.groups if hasattr(g, "registry")).registry
    assert registry.crack_count() == 1
    assert {len(g.localized()) > 0 for g in s.built.embeddeds} == {True}  # both regions are cut
    assert s.result.completed
    assert h["F_axial"][-1] == pytest.approx(P * W, rel=5e-3)


def test_two_cracks_each_with_its_own_enrichment(tmp_path):
    """Two given parallel cracks 8 mm apart, the second four times stronger: each cuts its cells with
    an enrichment of its own; the first slides to the residual (p w within 0.5 %) while the second
    holds (no point of it yields; its jump stays the elastic one, below 1e-3 of the first's slip)."""
    case = shortened(crack_case(block(16, 32)))
    first = case["embedded"]["cracks"][0]
    second = {"points": [[x, y - 0.008] for x, y in first["points"]], "c_p": 4 * first["c_p"]}
    case["embedded"]["cracks"].append(second)
    case["embedded"]["max_cracks"] = 2
    case["solver"] = {"max_iterations": 12}  # converged steps take at most 7: failed attempts stop sooner
    s = run_case(parse_case(case), tmp_path / "o")
    h = read_csv(tmp_path / "o" / "history.csv")
    assert s.result.completed
    assert h["F_axial"][-1] == pytest.approx(P * W, rel=5e-3)
    g = s.built.embeddeds[0]
    assert g.registry.crack_count() == 2
    points = {}
    for crack in np.unique(g.crack_of_cell[g.crack_of_cell >= 0]):
        rows = g.cut_slot[g.crack_of_cell == crack]
        points[int(crack)] = g.cc_cp[rows].reshape(-1, EP.N_CP)
    weak, strong = sorted(points.values(), key=lambda cp: -np.abs(cp[:, EP.CP_J]).max())
    assert np.all(strong[:, EP.CP_ZETA] == 0.0) and np.all(strong[:, EP.CP_JP:EP.CP_JP + 2] == 0.0)
    assert np.abs(strong[:, EP.CP_J]).max() < 1e-3 * np.abs(weak[:, EP.CP_J]).max()


def band_path(s, onset_tolerance_deg: float = 3.0, interior: float = 0.75) -> np.ndarray:
    """Checks that the cut cells' segments make one continuous path from the left edge to the right
    one, straight within onset_tolerance_deg of the first cell's bifurcation angle over x < interior W;
    returns every segment's angle [deg] in the order along x."""
    emb = s.built.embeddeds
    seg = np.vstack([g.segments[g.localized()] for g in emb])
    chain(seg, 1e-9 * W)
    assert seg[..., 0].min() == pytest.approx(0.0, abs=1e-9) and seg[..., 0].max() == pytest.approx(W, abs=1e-9)
    d = seg[:, 1] - seg[:, 0]
    angles = np.degrees(np.arctan2(np.abs(d[:, 1]), np.abs(d[:, 0])))
    onset = math.degrees([o for g in emb for o in g.onsets][0].band_angle)
    mid = seg[..., 0].mean(axis=1)
    assert np.max(np.abs(angles[mid < interior * W] - onset)) < onset_tolerance_deg
    return angles[np.argsort(mid)]


@pytest.fixture(scope="module")
def band(tmp_path_factory):
    out = tmp_path_factory.mktemp("band")
    mesh = {"kind": "block", "element": "quad4", "width": W, "height": 0.08, "nx": 12, "ny": 24,
            "inclusion": [0.0, 0.0067, 0.0034, 0.0167]}
    case = nodal(band_case(mesh, {"tracking": "nonlocal", "tracking_length": 0.01}))
    case["loading"]["max_steps"] = 600
    case["output"]["picture"] = False  # no crack_map.png: nothing here looks at it
    return out, run_case(parse_case(case), out)


def test_a_grown_band_crosses_straight_and_ends_at_the_closed_form(band):
    """The band grown in yielded rock reaches the right edge as one continuous path, within 3 degrees
    of its bifurcation angle over the first three quarters of the width (over the last quarter its
    tip, the stress field of a sliding crack ahead of it, turns upward by up to 6 degrees: the
    elemental band, whose cut cells carry stress across, does not); with its strengths gone
    (c < 1 Pa), the force is within 2 % of the closed form of the band at its mean angle (p w),
    where the elemental EDE's band ends at 1.5-1.8 times it."""
    out, s = band
    assert s.result.completed
    angles = band_path(s)
    assert np.ptp(angles) < 8.0
    reference, c_left = closed_form(s)
    assert c_left < 1.0
    assert reference == pytest.approx(P * W, rel=1e-3)
    force = read_csv(out / "history.csv")["F_axial"]
    assert force[-1] == pytest.approx(reference, rel=0.02)


def test_the_band_balances_its_energy(band):
    """The external work is the stored energy plus the dissipation plus what the cuts release
    (E_released: a cut changes the discrete system at fixed displacement: the closed tip edge it
    opens lets go of the force it held, which the next step relaxes, and the cut cell's new
    quadrature changes its stored energy), to 1e-9 of the dissipation at every step; the cuts'
    share is small (below 2 % of the dissipation), and the crack's law accounts for its own share
    (D_surface_law, the work of its tractions on its plastic jumps)."""
    out, s = band
    h = read_csv(out / "history.csv")
    assert np.abs(h["energy_error"]).max() < 1e-9 * h["D_dissipated"][-1]
    assert 0.0 < abs(h["E_released"][-1]) < 2e-2 * h["D_dissipated"][-1]
    assert 0.0 < h["D_surface_law"][-1] < h["D_dissipated"][-1]


def test_a_crack_runs_as_far_as_the_load_drives_it_before_the_load_moves(band):
    """A commit that cuts cells is followed by a hold (rockfrac.solve.stepping): equilibrium at the
    same load factor (before path control takes over: the force only relaxes there) or at the same
    value of the path measure, a step of its own in history.csv ("hold"), whose commit opens the
    cells at the new tips that the stress after the cuts drives; so how far the crack runs at a load
    no longer depends on the next step's size. Every hold follows a commit with cuts, and the band
    runs most of its length in holds."""
    out, s = band
    h = read_csv(out / "history.csv")
    hold = np.flatnonzero(h["control"] == "hold")
    cut = h["n_localized"]
    assert hold.size >= 5 and np.all(hold > 1)
    assert np.all(cut[hold - 1] > cut[hold - 2])  # the commit before a hold cut cells
    loaded = hold[h["control"][hold - 1] == "load"]
    assert loaded.size >= 1
    assert np.all(h["u_axial"][loaded] == h["u_axial"][loaded - 1])
    assert np.all(h["F_axial"][loaded] <= h["F_axial"][loaded - 1] * (1.0 + 1e-12))
    in_holds = np.sum(np.diff(cut)[hold - 1])  # the cells cut at the commits of holds
    assert in_holds > 0.5 * cut[-1]


def test_a_tip_event_is_located_on_the_trial_stress(band):
    """The nonlocal stress at a crack tip is the committed one at a commit and the step's trial one in
    the step's event indicator, so shortening a step moves the indicator and the step lands on the
    tip's onset (with the committed stress in both, the indicator did not move, the step was cut
    by 0.9 again and again and a step of 0.85 mm went past the onset)."""
    out, s = band
    g = s.built.embeddeds[0]
    paths, length = g.paths, g.tracking_length
    point = np.array([0.5 * W, 0.04])
    committed = paths.nonlocal_stress(point, length)
    saved = [e.trial_sigma.copy() for e in paths.groups]
    try:
        for e in paths.groups:
            e.trial_sigma[:] = 2.0 * e.sigma + 1.0
        assert np.allclose(paths.nonlocal_stress(point, length, trial=True), 2.0 * committed + 1.0, rtol=1e-12)
        assert np.allclose(paths.nonlocal_stress(point, length), committed, rtol=0.0, atol=0.0)
    finally:
        for e, t in zip(paths.groups, saved):
            e.trial_sigma[:] = t
    landed = []  # (step's log line index, trial value) of each shortening in the run
    for line in (out / "run.log").read_text().splitlines():
        if "event indicator" in line:
            landed.append(line.split("->")[1].split()[0])
        elif line.startswith("step "):
            assert len(landed) == len(set(landed)), landed  # every shortening moved the indicator
            landed = []


def test_a_grown_band_on_unstructured_triangles(tmp_path):
    """On an unstructured Gmsh triangle mesh (3 mm) the band's path is continuous, crosses to the right
    edge within 3 degrees of its bifurcation angle over the first three quarters of the width, and
    softens to within 2 % of the closed form (the elemental EDE stops converging before the edge)."""
    msh = triangle_block(tmp_path / "block.msh", 0.003)
    case = nodal(band_case({"kind": "gmsh", "file": str(msh)}, {"tracking": "nonlocal", "tracking_length": 0.0075}))
    # to 2.4 mm at the band case's load step (2.67e-5 m): the band's strengths are gone (c < 0.5 Pa)
    case["loading"].update(axial_displacement=2.4e-3, axial_steps=90, max_steps=1000)
    case["output"]["picture"] = False
    s = run_case(parse_case(case), tmp_path / "out")
    assert s.result.completed
    band_path(s)
    reference, c_left = closed_form(s)
    assert c_left < 1.0
    force = read_csv(tmp_path / "out" / "history.csv")["F_axial"]
    assert force[-1] == pytest.approx(reference, rel=0.02)


def test_a_given_crack_under_in_situ_stress_slides_to_the_same_closed_form(tmp_path):
    """The given crack's case with its confinement given as an in-situ stress instead of a stage
    (sigma0: the confinement stage's plane-strain state, held by its tractions on the whole boundary;
    the top shortened from u = 0): the crack starts from sigma0 . n, and after full softening the
    top carries p w within 0.5 % (its reaction plus the in-situ traction it keeps), as the confined
    case (the in-situ share of the enriched unknowns where the crack crosses the loaded edges
    included, from t = 0 on)."""
    nu = 0.3
    case = crack_case(block(8, 16))
    assert case["materials"][0]["nu"] == nu
    loading = case.pop("loading")
    s_yy = nu / (1 - nu) * -P
    case["initial"] = {"stress": [{"stress": [-P, s_yy, nu * (-P + s_yy), 0.0]}]}
    case["stages"] = [{"name": "axial", "control": "path", "path_increment": loading["path_increment"],
                       "max_steps": loading["max_steps"], "steps": loading["axial_steps"],
                       "displacement": {"bottom": {"y": 0.0}, "bottom_left": {"x": 0.0},
                                        "top": {"y": -loading["axial_displacement"]}}}]
    s = run_case(parse_case(case), tmp_path / "o")
    h = read_csv(tmp_path / "o" / "history.csv")
    assert s.result.completed, s.result.message
    force = -np.asarray(h["R_top_y"]) - s_yy * W  # the top's reaction and the in-situ traction on it
    e_yy = -2e-3 * np.asarray(h["load_factor"][:3]) / 0.08  # the first steps: elastic, the crack closed
    # (the crack's penalty adds its small compliance: 0.07 % here; from zero, the start would be off by s_yy w)
    np.testing.assert_allclose(force[:3], -s_yy * W - 1.5e7 / (1 - nu**2) * e_yy * W, rtol=2e-3)
    assert force.max() > 3 * P * W
    assert force[-1] == pytest.approx(P * W, rel=5e-3)
    assert abs(h["energy_error"][-1]) <= 1e-6 * h["W_external"][-1]
