"""Every example validates and runs (small), every mesh script writes a mesh, every Python snippet of
the README runs; each run's energy balance closes."""

from __future__ import annotations

import re
import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest

from rockfrac.bifurcation_cli import load_material
from rockfrac.case.schema import load_case, load_law, parse_case
from rockfrac.mesh.gmsh_io import read_mesh
from rockfrac.runner import run_case

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"
TOMLS = sorted(EXAMPLES.rglob("*.toml"))
CASES = [p for p in TOMLS if "[law]" not in p.read_text() and "[material]" not in p.read_text()]
TESTED_ELSEWHERE = {"rock_tests"}  # run with their closed forms in test_rock_tests.py


def test_every_example_file_validates():
    assert len(TOMLS) >= 15
    for p in TOMLS:
        text = p.read_text()
        if "[law]" in text:
            load_law(p)
        elif "[material]" in text:
            load_material(p)
        else:
            load_case(p)


#: examples whose mesh file their mesh.py writes: the options of a coarse one (as the mesh script test's)
COARSE_MESH_FILES = {"aggregate_3d": ["--cells", "3", "3", "6", "--grains", "4"]}


def small(path: Path, folder: Path | None = None) -> dict:
    """The case of an example file made small: coarser generated meshes (a mesh file its mesh.py
    writes: written coarse into ``folder``), at most 12 steps a stage (the same loads: larger
    increments)."""
    data = tomllib.loads(path.read_text())
    mesh = data.get("mesh", {})
    if mesh.get("file"):
        mesh["file"] = str((path.parent / mesh["file"]).resolve())
    coarse = COARSE_MESH_FILES.get(path.parent.name)
    if coarse is not None and folder is not None:
        out = folder / Path(mesh["file"]).name
        subprocess.run([sys.executable, str(path.parent / "mesh.py"), *coarse, "--out", str(out)], check=True,
                       capture_output=True)
        mesh["file"] = str(out)
    if mesh.get("kind") == "block" and mesh.get("element") not in ("hex8", "tet4"):  # (the 3D prisms are small)
        mesh["nx"], mesh["ny"] = max(2, mesh.get("nx", 1) // 4), max(2, mesh.get("ny", 1) // 4)
    if mesh.get("kind") == "grains":
        mesh.update(n_grains=min(mesh.get("n_grains", 60), 8), element_size=mesh.get("width", 0.04) / 12)
    if "loading" in data:
        load = data["loading"]
        load["axial_steps"] = min(load["axial_steps"], 12)
        if "max_steps" in load:
            load["max_steps"] = min(load["max_steps"], 20)
    for st in data.get("stages", []):
        st["steps"] = min(st.get("steps", 1), 12)
        if "max_steps" in st:
            st["max_steps"] = min(st["max_steps"], 20)
    data.setdefault("output", {}).update(picture=False, vtk=False)
    return data


@pytest.mark.parametrize("path", [p for p in CASES if not TESTED_ELSEWHERE & set(p.parts)],
                         ids=lambda p: str(p.relative_to(EXAMPLES)))
def test_every_example_case_runs_small(tmp_path, path):
    summary = run_case(parse_case(small(path, tmp_path), str(path)), tmp_path / "o")
    from rockfrac.output.csvout import read_csv

    h = read_csv(tmp_path / "o" / "history.csv")
    assert summary.result.steps >= 1 and len(h["step"]) == summary.result.steps
    scale = max(np.abs(h["W_external"]).max(), np.abs(h["E_elastic"]).max(), 1e-300)
    assert np.abs(h["energy_error"]).max() <= 1e-7 * scale


@pytest.mark.parametrize("script", sorted(EXAMPLES.rglob("mesh.py")), ids=lambda p: p.parent.name)
def test_every_mesh_script_writes_a_mesh(tmp_path, script):
    out = tmp_path / "m.msh"
    size = {"brazilian": ["--size", "0.01"], "borehole": ["--size", "0.02"], "bending": ["--size", "0.01"],
            "triaxial": ["--size", "0.02"], **COARSE_MESH_FILES,
            "embedded_3d": ["--divisions", "4", "2", "8"]}
    subprocess.run([sys.executable, str(script), *size[script.parent.name], "--out", str(out)], check=True,
                   capture_output=True, timeout=300)
    mesh = read_mesh(out, dim=None)
    kind = {"triaxial": "tet4", "aggregate_3d": "tet4", "embedded_3d": "hex8"}.get(script.parent.name, "quad4")
    assert mesh.cells.shape[0] > 10 and mesh.cell_type == kind


def readme_snippets() -> list[str]:
    return re.findall(r"```python\n(.*?)```", (ROOT / "README.md").read_text(), flags=re.S)


def test_the_readme_has_python_snippets():
    assert len(readme_snippets()) >= 2


@pytest.mark.parametrize("k", range(len(readme_snippets())))
def test_every_readme_python_snippet_runs(tmp_path, monkeypatch, k):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "examples").symlink_to(EXAMPLES)
    exec(compile(readme_snippets()[k], f"README.md snippet {k + 1}", "exec"), {"__name__": "__readme__"})
