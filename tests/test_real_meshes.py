"""Cohesive sets on split meshes, junctions, and the case keys of real meshes."""

import numpy as np
import pytest

from conftest import EVERY_EDGE, check_tied_every_edge

from rockfrac.case.schema import CaseError, parse_case
from rockfrac.output.csvout import read_csv
from rockfrac.runner import run_case
from rockfrac.studies import table1

BASE = EVERY_EDGE


def test_rp_on_every_edge_reproduces_the_unsplit_solution_and_physical_junction_tractions(tmp_path):
    """Every internal edge split (4 copies of every interior node: loops of pairs) and tied by
    constrained RP surfaces: the unsplit elastic response exactly, no jump, and at the junctions
    the multipliers are the physical tractions sigma . n (least circulation)."""
    run_case(parse_case(BASE), tmp_path / "a")
    s = run_case(parse_case(dict(BASE, cohesive=dict(table1.CSE_LAW, form="rp", where="all"))), tmp_path / "b")
    assert s.result.completed
    assert s.built.mesh.n_nodes == 4 * 4 * 6  # every cell has its own corners
    check_tied_every_edge(tmp_path / "a", tmp_path / "b", rtol=1e-7, jump=1e-12)
    # the user is told that such surfaces cannot open one at a time inside the mesh: the 3 x 5
    # interior nodes' loops of 4 pairs (60 points); the paper's one RP crack gets no such warning
    loops = [w for w in s.warnings or [] if "lie on loops of surfaces round a node" in w]
    assert len(loops) == 1 and "60 of its points" in loops[0]
    paper = run_case(parse_case(dict(BASE, mesh=dict(BASE["mesh"], crack=True),
                                     cohesive=dict(table1.CSE_LAW, form="rp"))), tmp_path / "c")
    assert not any("loops of surfaces" in w for w in paper.warnings or [])


def test_ep_on_every_edge_is_softer_by_its_penalties(tmp_path):
    """EP on every edge: each layer of horizontal surfaces adds 1/kn of compliance."""
    run_case(parse_case(BASE), tmp_path / "a")
    k = 1e10
    s = run_case(parse_case(dict(BASE, cohesive=dict(table1.CSE_LAW, form="ep", where="all", kn=k, kt=k))),
                 tmp_path / "b")
    a, b = read_csv(tmp_path / "a" / "history.csv"), read_csv(tmp_path / "b" / "history.csv")
    ax = a["stage"] == "axial"
    slope_a = np.polyfit(a["u_axial"][ax], a["F_axial"][ax], 1)[0]
    slope_b = np.polyfit(b["u_axial"][ax], b["F_axial"][ax], 1)[0]
    w, h, ny = 0.04, 0.08, 6
    e1 = 1.5e7 / (1 - 0.09)
    # series: bulk h/E' and (ny - 1) horizontal surfaces of compliance 1/kn (lateral coupling is second order)
    assert slope_b / slope_a == pytest.approx((h / e1) / (h / e1 + (ny - 1) / k), rel=2e-3)
    assert s.result.completed


@pytest.mark.parametrize("edit,expected", [
    ({"cohesive": dict(table1.CSE_LAW, form="rp", where="between", regions=["grains"])},
     "where = 'between' needs regions = a list of 2 region name(s)"),
    ({"cohesive": dict(table1.CSE_LAW, form="rp", where="between", regions=["grains", "matrix"])},
     "regions: region 'grains', 'matrix' not in the mesh; its regions: bulk"),
    ({"cohesive": dict(table1.CSE_LAW, form="rp", where="curves", curves=["fault"])},
     "curves: curve group 'fault' not in the mesh"),
    ({"loading": dict(BASE["loading"], axial="lid")}, "[loading] axial: node group 'lid' not in the mesh"),
    ({"materials": [{"region": "rock", "E": 1e7, "nu": 0.2}]}, "give either [bulk] (one material everywhere) or [[materials]]"),
    ({"mesh": {"kind": "gmsh"}}, "kind = 'gmsh' needs file"),
    ({"mesh": {"kind": "block", "crack_angle": 0.3}}, "crack_angle do not apply to kind = 'block'"),
    ({"mesh": {"kind": "specimen", "element": "tet4"}}, "element = 'tet4' is for kind = 'block'"),
    ({"mesh": {"kind": "block", "nz": 2}}, "nz only apply to element = 'hex8' or 'tet4'"),
    ({"mesh": {"kind": "block", "points_per_circle": 48}}, "points_per_circle do not apply to kind = 'block'"),
    ({"mesh": {"kind": "grains", "points_per_circle": 6}}, "points_per_circle"),
    ({"mesh": {"kind": "block", "element": "tet4", "nx": 2, "ny": 2},
      "cohesive": dict(table1.CSE_LAW, form="ep", where="all", kn=1e10, kt=1e10)},
     "cohesive surfaces of a generated 3D mesh are not made: not with element = 'tet4'"),
])
def test_bad_real_mesh_cases_name_the_key(tmp_path, edit, expected):
    from rockfrac.case.build import build

    case = dict(BASE, **edit)
    with pytest.raises(CaseError) as err:
        build(parse_case(case, "c.toml"), "c.toml")
    assert expected in str(err.value) and "c.toml" in str(err.value)


def test_local_tracking_gives_one_continuous_band_across_the_mesh(tmp_path):
    """A small version of examples/band: the band starts in the weak inclusion (another material,
    another group) and every next cut cell continues it from the point where the previous surface
    leaves it, up to the boundary."""
    import tomllib
    from pathlib import Path

    d = tomllib.loads((Path(__file__).resolve().parents[1] / "examples" / "band" / "band.toml").read_text())
    d["mesh"].update(nx=10, ny=20, inclusion=[0.0, 0.036, 0.004, 0.044])
    d["output"] = {"vtk": False}
    d["loading"].update(axial_steps=150, max_steps=120, path_increment=1e-5)
    s = run_case(parse_case(d), tmp_path)
    emb = s.built.embeddeds
    seg = np.vstack([g.segments[g.localized()] for g in emb])
    regions = {g.region for g in emb if g.localized().size}
    assert seg.shape[0] >= 10 and regions == {"weak", "bulk"}  # across the material boundary
    # one chain: every segment but the first starts where another one ends
    starts, ends = seg[:, 0], seg[:, 1]
    linked = [np.min(np.linalg.norm(ends - p, axis=1)) < 1e-9 for p in starts]
    assert sum(not x for x in linked) == 1
    assert np.isclose(seg[:, :, 0].min(), seg[:, :, 0].min()) and (
        np.isclose(seg[:, :, 1].max(), 0.08) or np.isclose(seg[:, :, 0].max(), 0.04))  # reaches the boundary
    h = read_csv(tmp_path / "history.csv")
    assert h["F_axial"][-1] < 0.95 * h["F_axial"].max()  # the specimen softens
    # the crack map of the last step draws exactly these segments
    assert (tmp_path / "crack_map.png").stat().st_size > 10_000
    assert f"crack_map.png: step {s.result.steps}, {seg.shape[0]} crack segments" in (tmp_path / "run.log").read_text()
