"""The command line and the error messages for bad input files."""

import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from rockfrac.case.schema import CaseError, load_case
from rockfrac.cli import main
from rockfrac.output.csvout import read_csv

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"


def write(tmp_path, text: str, name: str = "case.toml") -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


GOOD = (EXAMPLES / "paper" / "cse_rp.toml").read_text()


@pytest.mark.parametrize("name", ["cse_ep_k1e9", "cse_ep_k1e8", "cse_rp"])
def test_paper_cases_validate(name):
    case = load_case(EXAMPLES / "paper" / f"{name}.toml")
    assert case.bulk.E == 1.5e7 and case.loading.confinement == 2e4
    coh = case.cohesive_sets[0]
    assert coh.c_p == 9053.0 and coh.alpha_c == (2e2 if name.endswith("1e8") else 2e3)


@pytest.mark.parametrize(
    "edit,expected",
    [
        (("nu = 0.3", "nu = 0.5"), "[bulk] nu: Input should be less than 0.5"),
        (("c_p = 9053.0", "c_p = -1.0"), "[cohesive] c_p: Input should be greater than or equal to 0"),
        (("GfI = 1e4", "GfI = 1e4\nGfIII = 3"), "[cohesive] GfIII: unknown key; allowed keys: GfI"),
        (("[bulk]\nE = 1.5e7\nnu = 0.3", ""), "give either [bulk] (one material everywhere) or [[materials]]"),
        (('form = "rp"', 'form = "rp"\nkn = 1e9'), "kn only apply to form = 'ep'"),
        (('form = "rp"', 'form = "ep"'), "form = 'ep' needs kn, kt"),
        (('form = "rp"', 'form = "xp"'), "[cohesive] form: Input should be 'ep' or 'rp'"),
        (("crack_angle = 0.9989762274499867", "crack_angle = 1.4"), "[mesh] crack_angle: a crack at 80.21 deg"),
        (("axial_steps = 400", "axial_steps = 0"), "[loading] axial_steps: Input should be greater than or equal to 1"),
        (("[loading]", "[loading]\ncontrol = 'arc'"), "[loading] control: Input should be 'displacement' or 'path'"),
    ],
)
def test_bad_case_files_get_a_clear_error_before_any_step(tmp_path, capsys, edit, expected):
    old, new = edit
    assert old in GOOD
    path = write(tmp_path, GOOD.replace(old, new))
    out = tmp_path / "out"
    assert main(["run", str(path), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert str(path) in err.replace("\n", "")
    assert expected in " ".join(err.split()), err
    assert "Traceback" not in err
    assert not (out / "history.csv").exists()


def test_unreadable_files(tmp_path):
    with pytest.raises(CaseError, match="no such file"):
        load_case(tmp_path / "missing.toml")
    with pytest.raises(CaseError, match="not valid TOML"):
        load_case(write(tmp_path, "[bulk\nE = 1"))


def test_run_writes_history_points_resolved_case_and_log(tmp_path):
    text = GOOD.replace("axial_displacement = 4e-3", "axial_displacement = 6e-4").replace(
        "axial_steps = 400", "axial_steps = 30")
    path = write(tmp_path, text)
    assert main(["run", str(path), "--out", str(tmp_path / "o"), "--quiet"]) == 0
    h = read_csv(tmp_path / "o" / "history.csv")
    for col in ("step", "u_axial", "F_axial", "newton_iterations", "jump_p_norm", "chi", "c", "tan_phi", "tan_psi"):
        assert col in h
    pts = read_csv(tmp_path / "o" / "points.csv")
    assert set(pts["state"]) == {"constrained", "plastic"}
    assert len(pts["step"]) == 2 * len(h["step"])  # two node pairs on the crack
    resolved = load_case(tmp_path / "o" / "case.toml")
    from rockfrac.case.build import law_of_section

    bulk_r = 1.5e7 / np.sqrt(0.04 * 0.08 / 2)
    law_r = 10 * law_of_section(resolved.cohesive_sets[0]).softening_modulus()
    assert law_r > bulk_r  # Table 1 softens fast enough that the law sets the default
    assert resolved.cohesive_sets[0].augmentation == pytest.approx(law_r)
    assert "residual" in (tmp_path / "o" / "run.log").read_text()


def test_drive_cli_writes_the_law_along_the_path(tmp_path):
    out = tmp_path / "d"
    assert main(["drive", str(EXAMPLES / "laws" / "cse_law.toml"), "--path",
                 str(EXAMPLES / "laws" / "opening_path.csv"), "--out", str(out)]) == 0
    d = read_csv(out / "drive.csv")
    assert list(d) == ["step", "jump_t", "jump_n", "T_t", "T_n", "jump_p_t", "jump_p_n", "eps_n_p",
                       "eps_s_p", "chi", "c", "tan_phi", "tan_psi"]
    assert np.all(d["T_t"] == 0.0)
    plastic = d["jump_p_n"] > 0
    # at the degenerate apex of Table 1 the opening is resisted by chi itself
    np.testing.assert_allclose(d["T_n"][plastic], d["chi"][plastic], rtol=1e-8)


def test_drive_rejects_a_bad_path_file(tmp_path, capsys):
    bad = write(tmp_path, "jump_t,opening\n0,1\n", "path.csv")
    assert main(["drive", str(EXAMPLES / "laws" / "cse_law.toml"), "--path", str(bad), "--out", str(tmp_path)]) == 2
    assert "missing column(s) jump_n" in capsys.readouterr().err


def test_console_script_is_installed():
    exe = shutil.which("rockfrac", path=str(Path(sys.executable).parent))
    assert exe is not None
    res = subprocess.run([exe, "--help"], capture_output=True, text=True, check=True)
    assert "run" in res.stdout and "drive" in res.stdout
