"""Checkpoints and --resume reproduce an uninterrupted run; the ParaView series of a run."""

import xml.etree.ElementTree as ET

import meshio
import numpy as np
import pytest

from rockfrac.case.schema import CaseError, parse_case
from rockfrac.output.csvout import read_csv
from rockfrac.runner import run_case
from rockfrac.studies import table1


class Interrupt(Exception):
    pass


def interrupted_then_resumed(case, tmp_path, at: int):
    def stop(row):
        if row["step"] == at:
            raise Interrupt()

    with pytest.raises(Interrupt):
        run_case(case, tmp_path / "cut", progress=stop)
    return run_case(case, tmp_path / "cut", resume=True)


@pytest.mark.parametrize("name", ["rp_path", "ede", "ep_implex", "ep_viscous", "rp_viscous", "joint_3d", "nodal",
                                  "beam_edges"])
def test_resume_reproduces_the_uninterrupted_history(tmp_path, name):
    at = 70
    if name == "beam_edges":  # RP edge points whose bending is on its cap (its plastic part and force are kept)
        from test_rock_tests import example

        from rockfrac.mesh import rock_tests as rt

        d = example("bending/notched_beam.toml", rt.notched_beam(tmp_path / "beam.msh", element_size=0.0025),
                    **{"0__steps": 500})
        d["cohesive"]["points"] = "edges"
    elif name == "joint_3d":  # a 3D EP surface (tetrahedra, wedge interfaces in the VTK series)
        import tomllib
        from pathlib import Path

        folder = Path(__file__).resolve().parents[1] / "examples" / "rock_tests" / "triaxial"
        d = tomllib.loads((folder / "joint.toml").read_text())
        d["mesh"]["file"] = str(folder / d["mesh"]["file"])
        d["stages"][1].update(steps=35, displacement={"top": {"z": -3.5e-4}})  # the example's step; slips from step 15
        at = 30
    elif name == "nodal":  # a band of nodal embedded cracks, cut before and after the checkpoint
        from test_crack_tracking import band_case

        d = band_case({"kind": "block", "element": "quad4", "width": 0.04, "height": 0.08, "nx": 12, "ny": 24,
                       "inclusion": [0.0, 0.0067, 0.0034, 0.0167]}, {"tracking": "nonlocal", "tracking_length": 0.01})
        d["embedded"].update(kinematics="nodal", kn=1e10, kt=1e10)
        d["loading"].update(axial_displacement=1.2e-3, max_steps=120)
        d["output"] = {"points": True}
    elif name == "rp_path":
        d = table1.cse_case("rp", axial_steps=120, control="path", axial_displacement=2e-3)
    elif name == "ep_implex":  # the extrapolation's history (last plastic jumps, step size) is kept
        d = table1.cse_case("ep", 1e9, axial_steps=120, axial_displacement=4e-3)
        d["cohesive"]["integration"] = "implex"
    elif name in ("ep_viscous", "rp_viscous"):  # the overstress and D_viscous are kept
        d = table1.cse_case(name[:2], 1e9, axial_steps=120, axial_displacement=4e-3)
        d["cohesive"]["viscosity"] = 1e-3
    else:
        d = table1.ede_case(element="quad4", axial_steps=150)
    d["output"] = {"checkpoint_every": 25, "vtk": True, "vtk_every": 10}
    case = parse_case(d)
    run_case(case, tmp_path / "full")
    s = interrupted_then_resumed(case, tmp_path, at=at)
    assert s.result.completed
    for csv in ("history.csv", "points.csv"):
        a, b = read_csv(tmp_path / "full" / csv), read_csv(tmp_path / "cut" / csv)
        assert a.keys() == b.keys() and len(a["step"]) == len(b["step"])
        for k in a:
            if a[k].dtype.kind == "f":
                np.testing.assert_array_equal(a[k], b[k])  # bit for bit
            else:
                assert list(a[k]) == list(b[k])
    if name == "beam_edges":
        h = read_csv(tmp_path / "full" / "history.csv")
        assert h["D_bending"][25 * (at // 25) - 1] > 0.0  # the bending had yielded by the checkpoint
    log = (tmp_path / "cut" / "run.log").read_text()
    assert f"resumed from the checkpoint at step {25 * (at // 25)}" in log
    files = sorted((tmp_path / "cut" / "vtk").glob("*.vtu"))
    assert [f.name for f in files] == sorted(f.name for f in (tmp_path / "full" / "vtk").glob("*.vtu"))
    entries = ET.parse(tmp_path / "cut" / "vtk" / "results.pvd").getroot().iter("DataSet")
    assert [e.get("file") for e in entries] == [f.name for f in files]


def test_an_elastic_run_resumes(tmp_path):
    """A model whose only group keeps no state (an elastic solid) resumes from its checkpoint: the
    checkpoint counts its groups (before, it held no group's arrays and the resume refused it as
    written for another model), bit for bit, inside the second of two stages."""
    from conftest import pressed_then_pulled

    case = parse_case(pressed_then_pulled(4, 8))
    run_case(case, tmp_path / "full")
    assert interrupted_then_resumed(case, tmp_path, at=11).result.completed
    a, b = read_csv(tmp_path / "full" / "history.csv"), read_csv(tmp_path / "cut" / "history.csv")
    assert a.keys() == b.keys() and len(a["step"]) == len(b["step"]) == 12
    for k in a:
        if a[k].dtype.kind == "f":
            np.testing.assert_array_equal(a[k], b[k])
    assert "resumed from the checkpoint at step 10" in (tmp_path / "cut" / "run.log").read_text()


def test_resume_refuses_a_changed_case_or_no_checkpoint(tmp_path):
    d = table1.cse_case("rp", axial_steps=20, axial_displacement=6e-4)
    d["output"] = {"checkpoint_every": 5}
    run_case(parse_case(d), tmp_path / "o")
    d["loading"]["axial_steps"] = 30
    with pytest.raises(CaseError, match="the case differs"):
        run_case(parse_case(d), tmp_path / "o", resume=True)
    with pytest.raises(CaseError, match="no checkpoint here"):
        run_case(parse_case(d), tmp_path / "none", resume=True)


def test_a_checkpoint_written_before_a_key_existed_resumes(tmp_path):
    """A case.toml written by an older rockfrac lacks the keys added since (here [solver]
    max_iterations, taken out as if it were new), and its checkpoint's digest is of that text. Read
    with today's schema it is this case, so the run resumes, bit for bit the uninterrupted one. A case
    that differs, or a case.toml that is not the checkpoint's text, is still refused."""
    from rockfrac.output import checkpoint

    d = table1.cse_case("rp", axial_steps=40, axial_displacement=1.2e-3)
    d["output"] = {"checkpoint_every": 10}
    case = parse_case(d)
    run_case(case, tmp_path / "full")
    cut = tmp_path / "cut"

    def stop(row):
        if row["step"] == 25:
            raise Interrupt()

    with pytest.raises(Interrupt):
        run_case(case, cut, progress=stop)
    today = (cut / "case.toml").read_text()
    older = today.replace("max_iterations = 25\n", "")
    assert older != today and "max_iterations" not in older
    (cut / "case.toml").write_text(older)
    with np.load(cut / checkpoint.FILE) as z:  # the checkpoint as the older rockfrac wrote it
        arrays = {k: z[k] for k in z.files}
    arrays["meta.case_sha256"] = np.array(checkpoint.text_sha256(older))
    arrays["meta.payload_sha256"] = np.array(checkpoint._payload_sha256(arrays))
    np.savez(cut / checkpoint.FILE, **arrays)
    other = parse_case(dict(d, loading=dict(d["loading"], axial_steps=50)))
    with pytest.raises(CaseError, match="the case differs"):
        run_case(other, cut, resume=True)
    (cut / "case.toml").write_text(older + "# edited\n")  # not the text the checkpoint was written for
    with pytest.raises(CaseError, match="the case differs"):
        run_case(case, cut, resume=True)
    (cut / "case.toml").write_text(older)
    assert run_case(case, cut, resume=True).result.completed
    assert (cut / "case.toml").read_text() == today
    assert "resumed from the checkpoint at step 20" in (cut / "run.log").read_text()
    a, b = read_csv(tmp_path / "full" / "history.csv"), read_csv(cut / "history.csv")
    assert a.keys() == b.keys() and len(a["step"]) == len(b["step"]) >= 40
    for k in a:
        if a[k].dtype.kind == "f":
            np.testing.assert_array_equal(a[k], b[k])


def test_paraview_series_of_cracked_runs(tmp_path):
    d = table1.ede_case(element="quad4", axial_steps=150)
    d["output"] = {"vtk": True, "vtk_every": 150}
    run_case(parse_case(d), tmp_path / "ede")
    m = meshio.read(sorted((tmp_path / "ede" / "vtk").glob("*.vtu"))[-1])
    kinds = {c.type: len(c.data) for c in m.cells}
    assert kinds == {"quad": 1, "line": 1}  # the cell and its embedded segment
    jump = m.cell_data["jump"][1][0]
    p = read_csv(tmp_path / "ede" / "points.csv")
    at = p["step"] == 150
    np.testing.assert_allclose(jump, [p["jump_t"][at][0], p["jump_n"][at][0]], rtol=1e-12)
    assert m.cell_data["localized"][0][0] == 1 and np.isnan(m.cell_data["jump"][0][0]).all()
    d = table1.cse_case("rp", axial_steps=40, axial_displacement=1.5e-3)
    d["output"] = {"vtk": True, "vtk_every": 40}
    run_case(parse_case(d), tmp_path / "cse")
    m = meshio.read(sorted((tmp_path / "cse" / "vtk").glob("*.vtu"))[-1])
    kind = np.concatenate(m.cell_data["cell_kind"])
    assert (kind == 0).sum() == 2 and (kind == 1).sum() == 1  # two quads, one zero-thickness interface quad
    state = np.concatenate(m.cell_data["state"])[kind == 1][0]
    assert state == 2  # plastic
    disp = m.point_data["displacement"]
    assert disp.shape == (m.points.shape[0], 3) and np.abs(disp).max() > 1e-4
