"""The structure the code promises (README, Architecture): imports flow one way, from the bottom
layers to the top, and no group capability is probed with hasattr."""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "src" / "rockfrac"
LAYERS = ["errors", "values", "files", "_kernel_cache", "compiled", "threads", "analytic", "mesh", "fem", "laws", "elements",
          "model", "solve", "output", "case", "runner", "parallel", "api", "api_laws", "studies", "bifurcation_cli", "precompile",
          "cli"]


def layer(module: str) -> int:
    parts = module.split(".")
    return -1 if len(parts) == 1 else LAYERS.index(parts[1])


def modules():
    for f in sorted(PACKAGE.rglob("*.py")):
        name = ".".join(f.relative_to(PACKAGE.parent).with_suffix("").parts).removesuffix(".__init__")
        yield name, ast.parse(f.read_text())


def test_every_module_is_in_a_layer():
    for name, _ in modules():
        assert name == "rockfrac" or name.split(".")[1] in LAYERS, name


def test_imports_flow_one_way():
    """Every rockfrac import (module level or inside a function) goes to the same or a lower layer."""
    upward = []
    for name, tree in modules():
        for node in ast.walk(tree):
            targets = []
            if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("rockfrac"):
                targets = [node.module]
            elif isinstance(node, ast.Import):
                targets = [a.name for a in node.names if a.name.startswith("rockfrac")]
            for t in targets:
                if name != "rockfrac" and layer(t) > layer(name):
                    upward.append(f"{name}:{node.lineno} imports {t}")
    assert not upward, upward


def test_no_capability_probing():
    """Groups are used through their base class's methods, never probed or patched from outside."""
    found = [f"{name}:{node.lineno}" for name, tree in modules() for node in ast.walk(tree)
             if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "hasattr"]
    assert not found, found
