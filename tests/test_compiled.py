"""rockfrac.compiled: which functions may be compiled without a Python entry point, and what a
Python call to one does (issue 18: first-run compiling)."""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
SOURCES = ROOT / "src" / "rockfrac"
CALLERS = [SOURCES, ROOT / "tests", ROOT / "benchmarks", ROOT / "examples"]


def _decorators(node: ast.FunctionDef) -> list[str]:
    return [ast.unparse(d) for d in node.decorator_list]


def _compiled(node: ast.AST) -> bool:
    return isinstance(node, ast.FunctionDef) and any(
        d.split("(")[0] in ("kernel", "inner", "parallel_kernel") or "njit" in d for d in _decorators(node))


def _inner_functions() -> dict[str, str]:
    """name -> module file of every ``@inner`` function of the package."""
    found: dict[str, str] = {}
    for f in sorted(SOURCES.rglob("*.py")):
        for node in ast.walk(ast.parse(f.read_text())):
            if isinstance(node, ast.FunctionDef) and "inner" in _decorators(node):
                found[node.name] = str(f.relative_to(ROOT))
    return found


def _python_references(names: set[str], skip: tuple[str, ...] = ()) -> dict[str, list[str]]:
    """Where a name of ``names`` is read outside every compiled function's body (an import is not a
    use), in every file but ``skip``."""
    refs: dict[str, list[str]] = {}

    class Visitor(ast.NodeVisitor):
        def __init__(self, where: str):
            self.where, self.depth = where, 0

        def visit_FunctionDef(self, node: ast.FunctionDef) -> None:
            inside = _compiled(node)
            self.depth += inside
            self.generic_visit(node)
            self.depth -= inside

        def _use(self, name: str, node: ast.AST) -> None:
            if name in names and self.depth == 0:
                refs.setdefault(name, []).append(f"{self.where}:{getattr(node, 'lineno', 0)}")

        def visit_Name(self, node: ast.Name) -> None:
            self._use(node.id, node)

        def visit_Attribute(self, node: ast.Attribute) -> None:
            self._use(node.attr, node)
            self.generic_visit(node)

    for folder in CALLERS:
        for f in sorted(folder.rglob("*.py")):
            if str(f.relative_to(ROOT)) in skip:
                continue
            Visitor(str(f.relative_to(ROOT))).visit(ast.parse(f.read_text()))
    return refs


def test_inner_functions_are_called_from_compiled_code_only():
    inner = _inner_functions()
    assert len(inner) > 50  # the helpers of the laws, elements and assembly
    refs = _python_references(set(inner), skip=("tests/test_compiled.py",))  # calls one on purpose, below
    assert not refs, f"@inner functions used from Python (make them @kernel): {refs}"


def test_the_check_finds_a_python_use():
    """The source check sees a use from Python (so the test above can fail)."""
    refs = _python_references({"_jump_rows", "return_step"})
    assert set(refs) == {"_jump_rows"}  # the deliberate call of the test below, and nothing else
    assert all(w.startswith("tests/test_compiled.py:") for w in refs["_jump_rows"])


def test_every_compiled_function_goes_through_rockfrac_compiled():
    """No bare numba.njit in the package: one place sets the options (no C-callable wrapper, NumPy's
    error model) for every compiled function."""
    bare = []
    for f in sorted(SOURCES.rglob("*.py")):
        if f.name in ("compiled.py",):
            continue
        for node in ast.walk(ast.parse(f.read_text())):
            if isinstance(node, ast.FunctionDef) and any("njit" in d or "jit(" in d for d in _decorators(node)):
                bare.append(f"{f.relative_to(ROOT)}:{node.name}")
    assert not bare


def test_a_python_call_to_an_inner_function_raises():
    from rockfrac.laws import cohesive_system

    with pytest.raises(TypeError, match=r"cohesive_system\._jump_rows is compiled for compiled callers only"):
        cohesive_system._jump_rows(np.zeros(5), np.zeros(2), np.zeros(2), 0.0, 1.0, np.zeros(4), np.zeros(5),
                                   np.zeros((5, 5)))


def test_an_inner_function_runs_inside_a_kernel_and_is_cached(tmp_path):
    """An inner helper compiled inside a kernel gives the kernel's answer, and both are cached: a
    second process loads the kernel without compiling anything."""
    import subprocess
    import sys

    mod = tmp_path / "probe_inner.py"
    mod.write_text(
        "import numpy as np\n"
        "from rockfrac.compiled import inner, kernel\n"
        "@inner\n"
        "def half(x, out):\n"
        "    out[0] = 0.5 * x\n"
        "    return out[0] + 1.0\n"
        "@kernel\n"
        "def use(x):\n"
        "    o = np.empty(1)\n"
        "    return half(x, o) + o[0]\n")
    script = ("import sys; sys.path.insert(0, sys.argv[1]); import probe_inner as p; "
              "print(p.use(3.0), sum(p.use.stats.cache_hits.values()), sum(p.use.stats.cache_misses.values()))")
    env = {"NUMBA_CACHE_DIR": str(tmp_path / "cache"), "PATH": "/usr/bin:/bin"}
    runs = [subprocess.run([sys.executable, "-c", script, str(tmp_path)], capture_output=True, text=True, env=env,
                           check=True).stdout.split() for _ in range(2)]
    assert runs[0] == ["4.0", "0", "1"]  # compiled and written
    assert runs[1] == ["4.0", "1", "0"]  # loaded
