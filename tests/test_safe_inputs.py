"""Every malformed input gets one clean line naming the file and the key; no data file runs code.

The table drives the command line in-process with inputs a new user could write: each must exit
with code 2 before any step, print exactly one error line that names the file and the key (or
column, or row), and no traceback.
"""

from __future__ import annotations

import pickle
import zipfile
from pathlib import Path

import numpy as np
import pytest

from rockfrac.cli import main
from rockfrac.output import checkpoint

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"
GOOD = (EXAMPLES / "paper" / "cse_rp.toml").read_text()
LAW = (EXAMPLES / "laws" / "cse_law.toml").read_text()
MATERIAL = (EXAMPLES / "laws" / "dp_gosford.toml").read_text()
PATH_CSV = (EXAMPLES / "laws" / "shear_path.csv").read_text()


def solver(*lines: str) -> str:
    """GOOD with more keys in its [solver] table."""
    assert "\n[solver]\n" in GOOD
    return GOOD.replace("\n[solver]\n", "\n[solver]\n" + "".join(line + "\n" for line in lines))


def replace(old: str, new: str, text: str = GOOD) -> str:
    assert old in text, old
    return text.replace(old, new, 1)


def add(section: str, line: str, text: str = GOOD) -> str:
    return replace(f"[{section}]\n", f"[{section}]\n{line}\n", text)


GMSH_CASE = """
[mesh]
kind = "gmsh"
file = "MESHFILE"
[bulk]
E = 1.5e7
nu = 0.3
[loading]
confinement = 2e4
axial_displacement = 1e-4
axial_steps = 2
"""

# (id, case-file text) -> the key that must be named and what the message must say
CASES = [
    ("nu-nan", replace("nu = 0.3", "nu = nan"), "[bulk] nu", "finite"),
    ("E-inf", replace("E = 1.5e7", "E = inf"), "[bulk] E", "finite"),
    ("E-string", replace("E = 1.5e7", 'E = "1.5e7"'), "[bulk] E", "valid number"),
    ("E-bool", replace("E = 1.5e7", "E = true"), "[bulk] E", "valid number"),
    ("E-overflow", replace("E = 1.5e7", "E = 1e300"), "[bulk] E", "less than or equal"),
    ("E-zero", replace("E = 1.5e7", "E = 0"), "[bulk] E", "greater than 0"),
    ("steps-float", replace("axial_steps = 400", "axial_steps = 2.5"), "[loading] axial_steps", "valid integer"),
    ("steps-bool", replace("axial_steps = 400", "axial_steps = true"), "[loading] axial_steps", "valid integer"),
    ("steps-string", replace("axial_steps = 400", 'axial_steps = "10"'), "[loading] axial_steps", "valid integer"),
    ("steps-whole-float", replace("axial_steps = 400", "axial_steps = 10.0"), "[loading] axial_steps",
     "valid integer"),
    ("steps-huge", replace("axial_steps = 400", "axial_steps = 100000000000"), "[loading] axial_steps",
     "less than or equal"),
    ("confinement-negative", replace("confinement = 2e4", "confinement = -2e4"), "[loading] confinement",
     "greater than or equal to 0"),
    ("confinement-nan", replace("confinement = 2e4", "confinement = nan"), "[loading] confinement", "finite"),
    ("c_p-neg-inf", replace("c_p = 9053.0", "c_p = -inf"), "[cohesive] c_p", "finite"),
    ("c_p-overflow", replace("c_p = 9053.0", "c_p = 1e200"), "[cohesive] c_p", "less than or equal"),
    ("GfI-zero", replace("GfI = 1e4", "GfI = 0"), "[cohesive] GfI", "greater than 0"),
    ("phi-too-steep", replace("phi_p = 0.5236", "phi_p = 1.6"), "[cohesive] phi_p", "less than 1.57"),
    ("alpha-nan", replace("alpha_c = 2e3", "alpha_c = nan"), "[cohesive] alpha_c", "finite"),
    ("work-rule", add("cohesive", 'work_rule = "forward"'), "[cohesive] work_rule", "backward_euler"),
    ("augmentation-neg", add("cohesive", "augmentation = -1.0"), "[cohesive] augmentation", "greater than 0"),
    ("where-between", add("cohesive", 'where = "between"'), "[cohesive]", "needs regions"),
    ("residual-above-peak", replace("c_r = 0.0", "c_r = 1e5"), "[cohesive]", "must not exceed the peak"),
    ("unknown-section", GOOD + "\n[foo]\nx = 1\n", "foo", "unknown key"),
    ("unknown-key", add("mesh", "colour = 3"), "[mesh] colour", "unknown key"),
    ("mesh-kind", replace('kind = "specimen"', 'kind = "sphere"'), "[mesh] kind", "'specimen'"),
    ("mesh-nx-zero", replace("nx = 1", "nx = 0"), "[mesh] nx", "greater than or equal to 1"),
    ("mesh-nx-huge", replace("nx = 1", "nx = 1000000"), "[mesh] nx", "less than or equal"),
    ("mesh-cells-huge", replace("nx = 1\nny = 1", "nx = 10000\nny = 10000"), "[mesh]", "cells"),
    ("mesh-width-neg", replace("width = 0.04", "width = -0.04"), "[mesh] width", "greater than or equal"),
    ("mesh-width-huge", replace("width = 0.04", "width = 1e9"), "[mesh] width", "less than or equal"),
    ("crack-angle", replace("crack_angle = 0.9989762274499867", "crack_angle = 2.0"), "[mesh] crack_angle",
     "less than"),
    ("tol-zero", solver("tol_residual = 0.0"), "[solver] tol_residual", "greater than or equal"),
    ("tol-loose", solver("tol_residual = 1.0"), "[solver] tol_residual", "less than or equal"),
    ("min-step-zero", solver("min_step = 0.0"), "[solver] min_step", "greater than or equal"),
    ("cutback-one", solver("cutback = 1.0"), "[solver] cutback", "less than or equal"),
    ("grow-shrinks", solver("grow = 0.5"), "[solver] grow", "greater than or equal"),
    ("easy-negative", solver("easy_iterations = -1"), "[solver] easy_iterations", "greater than or equal"),
    ("iterations-zero", solver("max_iterations = 0"), "[solver] max_iterations",
     "greater than or equal"),
    ("linear-unknown", solver('linear = "cholmod"'), "[solver] linear", "'superlu'"),
    ("vtk-string", GOOD + '\n[output]\nvtk = "yes"\n', "[output] vtk", "valid boolean"),
    ("points-int", GOOD + "\n[output]\npoints = 1\n", "[output] points", "valid boolean"),
    ("checkpoint-negative", GOOD + "\n[output]\ncheckpoint_every = -1\n", "[output] checkpoint_every",
     "greater than or equal"),
    ("title-number", "title = 5\n" + GOOD.split("\n", 1)[1], "title", "valid string"),
    ("stop-fraction", add("loading", "stop_below_peak_fraction = 1.5"), "[loading] stop_below_peak_fraction",
     "less than 1"),
    ("axial-empty", replace("axial_displacement = 4e-3", "axial_displacement = []"), "[loading]",
     "at least one target"),
    ("axial-strings", replace("axial_displacement = 4e-3", 'axial_displacement = ["a"]'),
     "[loading] axial_displacement", "valid number"),
    ("axial-huge", replace("axial_displacement = 4e-3", "axial_displacement = 1e6"),
     "[loading] axial_displacement", "less than or equal"),
    ("path-increment-zero", add("loading", 'control = "path"\npath_increment = 0.0'), "[loading] path_increment",
     "greater than or equal"),
    ("control", add("loading", 'control = "arc"'), "[loading] control", "'displacement' or 'path'"),
    ("support-missing", add("loading", 'support = "nowhere"'), "[loading] support", "not in the mesh"),
    ("pressure-missing", add("loading", 'pressure = ["inner"]'), "[loading] pressure", "not in the mesh"),
    ("bulk-and-materials", GOOD + '\n[[materials]]\nregion = "bulk"\nE = 1e7\nnu = 0.2\n', "(top level)",
     "give either [bulk]"),
    ("dp-missing-beta", replace("nu = 0.3", 'nu = 0.3\nmodel = "drucker_prager"\nb = 0.1\nkappa0 = 1e4'),
     "[bulk]", "needs beta"),
    ("missing-loading", GOOD.split("[loading]")[0], "[loading]", "missing"),
    ("rp-with-kn", add("cohesive", "kn = 1e9"), "[cohesive]", "only apply to form = 'ep'"),
]


def _one_error_line(err: str) -> str:
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1, err
    assert "Traceback" not in err
    return lines[0]


def run_cli(capsys, *argv) -> tuple[int, str]:
    code = main([str(a) for a in argv])
    return code, capsys.readouterr().err


@pytest.mark.parametrize("name,text,key,says", CASES, ids=[c[0] for c in CASES])
def test_malformed_case_files(tmp_path, capsys, name, text, key, says):
    path = tmp_path / "case.toml"
    path.write_text(text)
    out = tmp_path / "out"
    code, err = run_cli(capsys, "run", path, "--out", out)
    line = _one_error_line(err)
    assert code == 2
    assert str(path) in line and key in line and says in line, line
    assert not (out / "history.csv").exists()


@pytest.fixture(scope="module")
def square_msh(tmp_path_factory) -> Path:
    """A 2 x 2 quad mesh of the unit square with the usual boundary groups, as MSH 4.1."""
    import gmsh

    path = tmp_path_factory.mktemp("mesh") / "square.msh"
    gmsh.initialize(readConfigFiles=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add("sq")
        s = gmsh.model.occ.addRectangle(0, 0, 0, 0.04, 0.08)
        gmsh.model.occ.synchronize()
        gmsh.model.addPhysicalGroup(2, [s], name="bulk")
        for name, tag in zip(("bottom", "right", "top", "left"), (1, 2, 3, 4)):
            gmsh.model.addPhysicalGroup(1, [tag], name=name)
        gmsh.model.addPhysicalGroup(0, [1], name="bottom_left")
        gmsh.model.mesh.setTransfiniteSurface(s)
        gmsh.model.mesh.setRecombine(2, s)
        gmsh.option.setNumber("Mesh.MeshSizeMax", 0.04)
        gmsh.model.mesh.generate(2)
        gmsh.write(str(path))
    finally:
        gmsh.finalize()
    return path


MESH_FILES = [
    ("missing", None, "no such file"),
    ("geo", "geo", "only Gmsh .msh mesh files"),
    ("geo-as-msh", "geo-as-msh", "not a Gmsh mesh file"),
    ("folder", "folder", "is a folder"),
    ("binary-garbage", "garbage", "not a Gmsh mesh file"),
    ("truncated", "truncated", "not a mesh Gmsh can read"),
    ("empty", "empty", "not a Gmsh mesh file"),
]


@pytest.mark.parametrize("name,kind,says", MESH_FILES, ids=[m[0] for m in MESH_FILES])
def test_malformed_mesh_files(tmp_path, capsys, square_msh, name, kind, says):
    marker = tmp_path / "ran"
    target = tmp_path / ("mesh.geo" if kind == "geo" else "mesh.msh")
    if kind in ("geo", "geo-as-msh"):
        target.write_text(f'SystemCall "touch {marker}";\nPoint(1) = {{0, 0, 0}};\n')
    elif kind == "folder":
        target.mkdir()
    elif kind == "garbage":
        target.write_bytes(bytes(range(256)) * 4)
    elif kind == "truncated":
        data = square_msh.read_bytes()
        target.write_bytes(data[: len(data) // 2])
    elif kind == "empty":
        target.write_text("")
    case = tmp_path / "case.toml"
    case.write_text(GMSH_CASE.replace("MESHFILE", target.name))
    code, err = run_cli(capsys, "run", case, "--out", tmp_path / "out")
    line = _one_error_line(err)
    assert code == 2
    assert str(case) in line and "[mesh] file" in line and says in line, line
    assert not marker.exists()


def test_the_good_mesh_file_runs(tmp_path, capsys, square_msh):
    case = tmp_path / "case.toml"
    case.write_text(GMSH_CASE.replace("MESHFILE", str(square_msh)))
    code, err = run_cli(capsys, "run", case, "--out", tmp_path / "out", "--quiet")
    assert code == 0, err


CASE_FILES = [
    ("missing", None, "no such file"),
    ("folder", "folder", "is a folder"),
    ("latin-1", b"title = \"caf\xe9\"\n", "not UTF-8"),
    ("not-toml", b"[bulk\nE = 1\n", "not valid TOML"),
    ("nul-bytes", b"title = \"a\"\x00\n", "NUL bytes"),
    ("empty", b"", "empty; a case file has"),
]


@pytest.mark.parametrize("name,content,says", CASE_FILES, ids=[c[0] for c in CASE_FILES])
def test_unreadable_case_files(tmp_path, capsys, name, content, says):
    path = tmp_path / "case.toml"
    if content == "folder":
        path.mkdir()
    elif content is not None:
        path.write_bytes(content)
    code, err = run_cli(capsys, "run", path, "--out", tmp_path / "out")
    line = _one_error_line(err)
    assert code == 2 and "Traceback" not in err
    assert str(path) in line and says in line, err


LAW_FILES = [
    ("kn-missing", LAW.replace("kn = 1e9\n", ""), "[law] kn", "missing"),
    ("GfI-nan", LAW.replace("GfI = 1e4", "GfI = nan"), "[law] GfI", "finite"),
    ("unknown-section", LAW + "\n[extra]\na = 1\n", "extra", "unknown key"),
    ("kt-string", LAW.replace("kt = 1e9", 'kt = "stiff"'), "[law] kt", "valid number"),
    ("chi-overflow", LAW.replace("chi_p = 15680.0", "chi_p = 1e300"), "[law] chi_p", "less than or equal"),
]


@pytest.mark.parametrize("name,text,key,says", LAW_FILES, ids=[c[0] for c in LAW_FILES])
def test_malformed_law_files(tmp_path, capsys, name, text, key, says):
    law = tmp_path / "law.toml"
    law.write_text(text)
    code, err = run_cli(capsys, "drive", law, "--path", EXAMPLES / "laws" / "shear_path.csv", "--out", tmp_path)
    line = _one_error_line(err)
    assert code == 2 and str(law) in line and key in line and says in line, line


PATHS = [
    ("missing-column", "jump_t,opening\n0,1\n", "missing column(s) jump_n"),
    ("non-numeric", "jump_t,jump_n\n0,abc\n", "row 2, column jump_n: 'abc' is not a number"),
    ("ragged", "jump_t,jump_n\n0,0\n1\n", "row 3 has 1 cells"),
    ("no-rows", "jump_t,jump_n\n", "no data rows"),
    ("empty", "", "empty"),
    ("nan", "jump_t,jump_n\n0,nan\n", "row 2, column jump_n: nan is not a finite number"),
    ("huge", "jump_t,jump_n\n0,1e10\n", "row 2, column jump_n: 1e10 is not a finite number"),
    ("duplicate", "jump_t,jump_n,jump_n\n0,0,0\n", "jump_n given twice"),
    ("latin-1", b"jump_t,jump_n\n0,0 \xe9\n", "not UTF-8"),
    ("missing-file", None, "no such file"),
]


@pytest.mark.parametrize("name,text,says", PATHS, ids=[p[0] for p in PATHS])
def test_malformed_path_csvs(tmp_path, capsys, name, text, says):
    path = tmp_path / "path.csv"
    if isinstance(text, bytes):
        path.write_bytes(text)
    elif text is not None:
        path.write_text(text)
    code, err = run_cli(capsys, "drive", EXAMPLES / "laws" / "cse_law.toml", "--path", path, "--out", tmp_path)
    line = _one_error_line(err)
    assert code == 2 and str(path) in line and says in line, line


MATERIALS = [
    ("E-string", MATERIAL.replace("E = 15000000.0", 'E = "x"'), "[material] E", "valid number"),
    ("stress-nan", MATERIAL.replace("syy = ", "syy = nan #"), "[stress] syy", "finite"),
]


@pytest.mark.parametrize("name,text,key,says", MATERIALS, ids=[m[0] for m in MATERIALS])
def test_malformed_material_files(tmp_path, capsys, name, text, key, says):
    path = tmp_path / "material.toml"
    path.write_text(text)
    code, err = run_cli(capsys, "bifurcation", path)
    line = _one_error_line(err)
    assert code == 2 and str(path) in line and key in line and says in line, line


def test_bad_stress_option(capsys):
    code, err = run_cli(capsys, "bifurcation", EXAMPLES / "laws" / "dp_gosford.toml", "--stress=nan,0,0,0")
    line = _one_error_line(err)
    assert code == 2 and "--stress" in line


def small_case(tmp_path: Path, steps: int = 20, extra: str = "") -> Path:
    text = replace("axial_steps = 400", f"axial_steps = {steps}").replace(
        "axial_displacement = 4e-3", "axial_displacement = 6e-4") + extra
    path = tmp_path / "case.toml"
    path.write_text(text)
    return path


def test_out_that_is_a_file_or_cannot_be_made(tmp_path, capsys):
    case = small_case(tmp_path)
    afile = tmp_path / "afile"
    afile.write_text("x")
    for out, says in ((afile, "--out is a file"), (afile / "sub", "cannot create the output folder")):
        code, err = run_cli(capsys, "run", case, "--out", out)
        line = _one_error_line(err)
        assert code == 2 and str(out) in line and says in line, line


def test_fresh_run_into_another_runs_folder_is_refused_or_cleared(tmp_path, capsys):
    out = tmp_path / "out"
    first = small_case(tmp_path, extra="\n[output]\nvtk = true\n")
    assert run_cli(capsys, "run", first, "--out", out, "--quiet")[0] == 0
    assert (out / "vtk").is_dir() and (out / "crack_map.png").exists()
    second = tmp_path / "second.toml"
    second.write_text(small_case(tmp_path, steps=10).read_text())
    code, err = run_cli(capsys, "run", second, "--out", out, "--quiet")
    line = _one_error_line(err)
    assert code == 2 and str(out) in line and "--overwrite" in line and "history.csv" in line
    mine = out / "notes.txt"
    mine.write_text("mine")
    assert run_cli(capsys, "run", second, "--out", out, "--quiet", "--overwrite")[0] == 0
    assert not (out / "vtk").exists()  # the stale series went with the rest
    assert mine.read_text() == "mine"  # what is not an output of a run is left alone
    rows = (out / "history.csv").read_text().splitlines()
    assert len(rows) == 1 + 2 + 10  # header, two confinement steps, ten axial steps: one run only


@pytest.fixture
def checkpointed(tmp_path, capsys):
    """A finished run with checkpoints every 5 steps: (case path, out folder)."""
    case = small_case(tmp_path, extra="\n[output]\ncheckpoint_every = 5\n")
    out = tmp_path / "out"
    assert run_cli(capsys, "run", case, "--out", out, "--quiet")[0] == 0
    assert (out / "checkpoint.npz").exists() and not (out / "checkpoint.pkl").exists()
    return case, out


class Payload:
    """Unpickling this creates the marker file: what a crafted checkpoint would do."""

    def __init__(self, marker: Path):
        self.marker = marker

    def __reduce__(self):
        return (Path.touch, (self.marker,))


def test_crafted_checkpoints_run_nothing(checkpointed, capsys):
    case, out = checkpointed
    marker = out.parent / "pwned"
    good = (out / "checkpoint.npz").read_bytes()
    # an old-style pickle checkpoint
    (out / "checkpoint.npz").unlink()
    (out / "checkpoint.pkl").write_bytes(pickle.dumps(Payload(marker)))
    code, err = run_cli(capsys, "run", case, "--out", out, "--resume")
    assert code == 2 and "never loaded" in _one_error_line(err) and not marker.exists()
    (out / "checkpoint.pkl").unlink()
    # a pickle under the new name
    (out / "checkpoint.npz").write_bytes(pickle.dumps(Payload(marker)))
    code, err = run_cli(capsys, "run", case, "--out", out, "--resume")
    assert code == 2 and "not a valid rockfrac checkpoint" in _one_error_line(err) and not marker.exists()
    # an archive holding a pickled object array
    with zipfile.ZipFile(out / "checkpoint.npz", "w") as z:
        with z.open("position.u.npy", "w") as fh:
            np.lib.format.write_array(fh, np.array([Payload(marker)], dtype=object), allow_pickle=True)
    code, err = run_cli(capsys, "run", case, "--out", out, "--resume")
    line = _one_error_line(err)
    assert code == 2 and "pickled objects" in line and not marker.exists(), line
    # truncated, and a bit flipped inside an intact archive
    (out / "checkpoint.npz").write_bytes(good[: len(good) // 2])
    code, err = run_cli(capsys, "run", case, "--out", out, "--resume")
    assert code == 2 and "truncated or corrupted" in _one_error_line(err)
    with np.load(_write(out, good), allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    arrays["position.u"] = arrays["position.u"] + 1e-3
    np.savez(out / "checkpoint.npz", **arrays)
    code, err = run_cli(capsys, "run", case, "--out", out, "--resume")
    assert code == 2 and "checksum" in _one_error_line(err)
    # a foreign archive
    np.savez(out / "checkpoint.npz", a=np.arange(3))
    code, err = run_cli(capsys, "run", case, "--out", out, "--resume")
    assert code == 2 and "another program" in _one_error_line(err)


def _write(out: Path, data: bytes) -> Path:
    (out / "checkpoint.npz").write_bytes(data)
    return out / "checkpoint.npz"


def test_resume_refuses_a_history_or_case_that_is_not_the_checkpoints(checkpointed, capsys):
    case, out = checkpointed
    history = out / "history.csv"
    original = history.read_text()
    lines = original.splitlines(keepends=True)
    lines[3] = lines[3].replace(",", ",1", 1)  # an early row (before the last checkpoint) changed
    history.write_text("".join(lines))
    code, err = run_cli(capsys, "run", case, "--out", out, "--resume")
    line = _one_error_line(err)
    assert code == 2 and str(history) in line and "mixes two runs" in line
    assert history.read_text() == "".join(lines)  # refused before touching anything
    history.unlink()
    code, err = run_cli(capsys, "run", case, "--out", out, "--resume")
    assert code == 2 and "missing" in _one_error_line(err)
    history.write_text(original)
    other = case.parent / "other.toml"
    other.write_text(case.read_text().replace("confinement = 2e4", "confinement = 1e4"))
    code, err = run_cli(capsys, "run", other, "--out", out, "--resume")
    assert code == 2 and "the case differs" in _one_error_line(err)
    assert run_cli(capsys, "run", case, "--out", out, "--resume", "--quiet")[0] == 0  # the right one resumes


def test_csv_quotes_fields_and_tells_nan_from_empty(tmp_path):
    from rockfrac.output.csvout import CsvWriter, read_csv

    w = CsvWriter(tmp_path / "t.csv", ["step", "name", "x", "y"])
    w.write({"step": 1, "name": "EP CSE, k = 1e8", "x": float("nan")})
    w.close()
    text = (tmp_path / "t.csv").read_text().splitlines()
    assert text[1] == '1,"EP CSE, k = 1e8",nan,'
    back = read_csv(tmp_path / "t.csv")
    assert back["name"][0] == "EP CSE, k = 1e8" and np.isnan(back["x"][0]) and np.isnan(back["y"][0])


def test_a_resumed_csv_takes_the_columns_added_since(tmp_path):
    """A run resumed by a rockfrac that writes a column more (history.csv's D_bending since 2026-12-02)
    keeps its old rows under the new header, the new column empty there, and its digest is the file's;
    a file with a column the run does not write is another run's: refused."""
    from rockfrac.output.csvout import CsvWriter, read_csv, rows_digest

    path = tmp_path / "h.csv"
    old = CsvWriter(path, ["step", "x", "E"])
    for k in (1, 2, 3):
        old.write({"step": k, "x": 0.5 * k, "E": 10.0 * k})
    old.close()
    new = CsvWriter(path, ["step", "x", "D_bending", "E"], keep_steps=2)
    new.write({"step": 3, "x": 7.0, "D_bending": 0.25, "E": 70.0})
    new.close()
    back = read_csv(path)
    np.testing.assert_array_equal(back["step"], [1, 2, 3])
    np.testing.assert_array_equal(back["x"], [0.5, 1.0, 7.0])
    np.testing.assert_array_equal(back["E"], [10.0, 20.0, 70.0])
    assert np.isnan(back["D_bending"][:2]).all() and back["D_bending"][2] == 0.25
    assert rows_digest(path, 3) == new.digest()
    with pytest.raises(ValueError, match=r"\['E'\] are not this run's"):
        CsvWriter(path, ["step", "x", "D_bending"], keep_steps=2)


def test_a_load_the_solve_cannot_follow_is_named(tmp_path, capsys):
    """A step that cannot converge down to min_step stops the run with the load key that drives it."""
    case = small_case(tmp_path, steps=1)
    case.write_text(case.read_text().replace("\n[solver]\n", "\n[solver]\nmax_iterations = 1\nmin_step = 0.25\n"))
    # one Newton iteration cannot meet the energy norm: the confinement stage fails
    out = tmp_path / "out"
    code, err = run_cli(capsys, "run", case, "--out", out, "--quiet")
    assert code == 1 and "Traceback" not in err
    text = " ".join(err.split())
    assert f"loads from {case}: [loading] confinement = 20000 Pa" in text, text
    assert "increment below min_step" in text
    assert "[loading] confinement" in (out / "run.log").read_text().splitlines()[-2]


def test_resume_refuses_a_checkpoint_of_another_size(checkpointed, capsys):
    """A checkpoint (intact, its checksum right) whose displacement vector is not this model's length
    is refused by name before anything is restored."""
    case, out = checkpointed
    saved = checkpoint.load(out)
    assert saved is not None
    position = {**saved.position, "u": saved.position["u"][:-2]}
    checkpoint.save(out, position, saved.groups, saved.run, saved.case_sha256, saved.history_sha256)
    code, err = run_cli(capsys, "run", case, "--out", out, "--resume")
    line = _one_error_line(err)
    assert code == 2 and "written for a different model" in line and "vector has" in line, line
