"""3D scaling: set-up, assembly, linear solve and memory from 1e4 to 1e6 dofs, direct and iterative.

One command (``.venv/bin/python benchmarks/scaling_3d.py``, about 20 minutes): an elastic unit box
of n x n x n cells, hex8 or tet4 (each hexahedron split into six tetrahedra by Gmsh), on rollers
(x = 0, y = 0, z = 0 held normally) under a pressure on the top, run as a rockfrac case (one load
step: the solve and Newton's check). Each (element, size, backend) runs in its own process (its own
peak memory): "set-up" is ``build(case)`` (Gmsh read, cells, CSR pattern and slot maps, constant
bulk matrix, stages); "solve" is every factorization and solve of the run; "assembly" is the rest
of the run (residuals, the tangent, Dirichlet rows). Every run is checked against the closed form
(u_z = -p z / E on the top, exact in these elements): the relative error is in the table.

``--problem plastic``: the same boxes of a hardening, nonassociative Drucker-Prager rock (a
non-symmetric tangent) in the paper's test: a lateral pressure on x = 1 with the top held, then two
axial strain steps of -4e-3 (the second yields), y held at both faces (plane strain). The stress is
homogeneous, so every mesh must give the material-point driver's axial stress
(``rockfrac.laws.dp_driver``, the same steps): its relative error is in the table.

``--problem joints-ep`` / ``joints-rp``: the elastic box as a stack of four slabs (rock_tests.box
layers=4) with cohesive joints on the three planes between them ([cohesive] where = 'boundaries'),
elasto-plastic (penalty kn = kt = 1e11 Pa/m) or rigid-plastic (augmented multipliers: a saddle-point
tangent), under the top pressure: uniaxial stress, so u_z = -p z / E - (joints below) p / kn (EP;
RP: the unsplit box's -p z / E) at every node, the table's error. ``joints-rp-nested``: the RP joints
with ``[cohesive] multipliers = "nested"`` (no multiplier unknowns; benchmarks/nested_multipliers.py).

Backends: ``pardiso`` (MKL, the default 'auto') and ``gmres-amg`` (GMRES(60) with pyamg's smoothed
aggregation on 3 x 3 nodal blocks and the six rigid-body modes, relative residual 1e-11).
Options: ``--sizes 1e4 1e5 3e5 1e6``, ``--elements hex8 tet4``, ``--backends pardiso gmres-amg``,
``--timeout`` (s per process), ``--quick`` (1e4 only, prints, writes nothing). Results go to
``benchmarks/results/scaling_3d[_plastic].json`` and the "3D scaling" tables of ``benchmarks/README.md``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).parent
E, NU, P = 2e10, 0.25, 1e6
# the plastic problem: the band example's hardening rock (E, nu, beta, b, H [Pa], kappa0 [Pa]) under a
# lateral pressure [Pa], then AXIAL_STEPS steps of AXIAL_STRAIN / AXIAL_STEPS
DP = {"model": "drucker_prager", "E": 1.5e7, "nu": 0.3, "beta": 0.480385, "b": 0.321597, "H": 43802.9,
      "kappa0": 15000.0}
CONFINEMENT, AXIAL_STRAIN, AXIAL_STEPS = 2e4, -8e-3, 2  # elastic, then yielding


LAYERS, KN = 4, 1e11  # the joints problems: slabs, EP penalty [Pa/m]
JOINT_LAW = {"GfI": 50.0, "GfII": 500.0, "chi_p": 1e6, "chi_r": 0.0, "c_p": 2e6, "c_r": 0.0, "phi_p": 0.6,
             "phi_r": 0.5, "psi_p": 0.1, "alpha_chi": 5.0, "alpha_c": 5.0, "alpha_phi": 5.0, "alpha_psi": 5.0}


def cells_for(dofs: float, problem: str = "elastic") -> int:
    """Cells per side of the box with about ``dofs`` unknowns (3 per node, (n + 1)^3 nodes); a
    multiple of the slabs for the joints problems."""
    n = max(2, round((dofs / 3) ** (1 / 3)) - 1)
    return max(LAYERS, LAYERS * round(n / LAYERS)) if problem.startswith("joints") else n


class TimedFactor:
    """A factorization whose solves are timed. A plain class: a class made inside ``factorize``
    would be a reference cycle keeping every factorization alive until Python's cyclic collector
    runs (it did, until 2026-11-25: the plastic table's peaks were 1.7-2x the engine's own)."""

    def __init__(self, factor, timing: dict):
        self.factor, self.timing = factor, timing

    def solve(self, b):
        t = time.perf_counter()
        x = self.factor.solve(b)
        self.timing["solve"] += time.perf_counter() - t
        if hasattr(self.factor, "iterations"):
            self.timing["gmres_iterations"].append(self.factor.iterations)
        return x


class TimedSolver:
    """The backend with its factorizations and solves timed into ``timing``."""

    def __init__(self, inner, timing: dict):
        self.inner, self.timing, self.name = inner, timing, inner.name

    def begin_step(self) -> None:
        self.inner.begin_step()

    def notes(self) -> list[str]:
        return self.inner.notes()

    def factorize(self, a):
        t = time.perf_counter()
        f = self.inner.factorize(a)
        self.timing["solve"] += time.perf_counter() - t
        self.timing["factorizations"] += 1
        return TimedFactor(f, self.timing)


def child_run(element: str, n: int, backend: str, folder: Path, problem: str = "elastic") -> dict:
    from rockfrac.case.build import build
    from rockfrac.case.schema import parse_case
    from rockfrac.mesh import rock_tests as rt
    from rockfrac.solve.linear import make_solver
    from rockfrac.solve.newton import NewtonOptions
    from rockfrac.solve.stepping import SteppingOptions, run_stages

    t0 = time.perf_counter()
    joints = problem.startswith("joints")
    msh = rt.box(folder / "box.msh", (1.0, 1.0, 1.0), (n, n, n), element=element, layers=LAYERS if joints else 1)
    t_mesh = time.perf_counter() - t0
    if problem == "plastic":
        held = {"left": {"x": 0.0}, "front": {"y": 0.0}, "back": {"y": 0.0}, "bottom": {"z": 0.0}}
        stages = [{"name": "confine", "displacement": dict(held, top={"z": 0.0}), "pressure": {"right": CONFINEMENT}},
                  {"name": "axial", "steps": AXIAL_STEPS, "displacement": dict(held, top={"z": AXIAL_STRAIN}),
                   "pressure": {"right": CONFINEMENT}}]
        spec = {"title": "box", "mesh": {"kind": "gmsh", "file": str(msh)}, "bulk": DP, "stages": stages,
                "solver": {"linear": backend}}
    else:
        spec = {"title": "box", "mesh": {"kind": "gmsh", "file": str(msh)}, "bulk": {"E": E, "nu": NU},
                "stages": [{"name": "press", "displacement": {"left": {"x": 0.0}, "front": {"y": 0.0},
                                                              "bottom": {"z": 0.0}},
                            "pressure": {"top": P}}], "solver": {"linear": backend}}
        if joints:
            form = problem.split("-")[1]
            spec["cohesive"] = {"where": "boundaries", "form": form, **JOINT_LAW,
                                **({"kn": KN, "kt": KN} if form == "ep" else {}),
                                **({"multipliers": "nested"} if problem.endswith("-nested") else {})}
    case = parse_case(spec, "box")
    t0 = time.perf_counter()
    built = build(case)
    t_setup = time.perf_counter() - t0
    inner = make_solver(backend, built.mesh.nodes, built.model.n_dofs)
    timing = {"solve": 0.0, "factorizations": 0, "gmres_iterations": []}

    sol = case.solver
    newton = NewtonOptions(sol.max_iterations, sol.tol_residual, sol.tol_energy,
                           force_scale=1e-6 * (DP["E"] if problem == "plastic" else E))
    state: dict = {"iterations": 0, "steps": 0}

    def on_step(info) -> None:
        state.update(u=info.u, f_int=info.f_int, iterations=state["iterations"] + info.newton.iterations,
                     steps=state["steps"] + 1)

    t0 = time.perf_counter()
    result = run_stages(built.model, built.stages, TimedSolver(inner, timing), newton, SteppingOptions(), on_step)
    t_run = time.perf_counter() - t0
    mesh = built.mesh
    u = state["u"][: 3 * mesh.n_nodes].reshape(-1, 3)
    top = mesh.node_sets["top"]
    if problem == "plastic":  # the top's reaction / area against the driver's axial stress (its y is our z)
        from rockfrac.laws.dp_driver import drive_specimen
        from rockfrac.laws.drucker_prager_params import DruckerPrager

        law = DruckerPrager(**{k: v for k, v in DP.items() if k != "model"})
        path = drive_specimen(law, confinement=CONFINEMENT, axial_strain=AXIAL_STRAIN, steps=AXIAL_STEPS,
                              locate=False)
        sigma_zz = float(state["f_int"][3 * top + 2].sum())  # unit area
        error = abs(sigma_zz - path.sigma[-1, 1]) / abs(path.sigma[-1, 1])
        assert path.mode[-1] != 0.0, "the driver's last step must be plastic"
    else:
        z = mesh.nodes[:, 2]
        exact = -P * z / E
        if problem == "joints-ep":  # each node's slab from a cell holding it (a joint's copies: one side each)
            slab = np.zeros(mesh.n_nodes)
            slab[mesh.cells.ravel()] = np.repeat(np.floor(mesh.nodes[mesh.cells][:, :, 2].mean(axis=1) * LAYERS),
                                                 mesh.cells.shape[1])
            exact = exact - slab * P / KN
        error = float(np.abs(u[:, 2] - exact).max() / np.abs(exact).max())
    return {"problem": problem, "element": element, "n": n, "backend": backend, "dofs": int(built.model.n_dofs),
            "cells": int(mesh.cells.shape[0]), "interfaces": int(len(mesh.interfaces)), "nnz": int(built.model.pattern.nnz),
            "completed": bool(result.completed), "newton_iterations": int(state["iterations"]),
            "steps": int(state["steps"]),
            "factorizations": timing["factorizations"], "gmres_iterations": timing["gmres_iterations"],
            "mesh_s": t_mesh, "setup_s": t_setup, "solve_s": timing["solve"],
            "assembly_s": t_run - timing["solve"], "run_s": t_run,
            "error": float(error),
            "peak_gib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20}


def child(args: list[str], timeout: float) -> dict:
    t0 = time.perf_counter()
    try:
        p = subprocess.run([sys.executable, __file__, *args], capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return {"failed": f"not finished in {timeout:.0f} s (killed)"}
    if p.returncode != 0:
        return {"failed": (p.stderr.strip().splitlines() or [f"exit code {p.returncode}"])[-1]}
    out = json.loads(p.stdout.strip().splitlines()[-1])
    out["wall_s"] = time.perf_counter() - t0
    return out


def machine() -> dict:
    from importlib import metadata

    cpu = next((line.split(":", 1)[1].strip() for line in Path("/proc/cpuinfo").read_text().splitlines()
                if line.startswith("model name")), platform.processor())
    mem = next(int(line.split()[1]) for line in Path("/proc/meminfo").read_text().splitlines()
               if line.startswith("MemTotal")) / 2**20
    return {"cpu": cpu, "cores": os.cpu_count(), "memory_gib": round(mem, 1), "python": platform.python_version(),
            "versions": {p: metadata.version(p) for p in ("numpy", "scipy", "numba", "pypardiso", "pyamg")},
            "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
            "load_before": [round(v, 2) for v in os.getloadavg()]}


def table(rows: list[dict], info: dict) -> str:
    head = (f"Machine: {info['cpu']}, {info['cores']} cores, {info['memory_gib']} GiB; Python {info['python']}, "
            + ", ".join(f"{k} {v}" for k, v in info["versions"].items())
            + f"; {info['date']}, load average before {info['load_before']}.\n\n"
            "| element | cells | dofs | backend | set-up [s] | assembly [s] | solve [s] | factorizations "
            "| GMRES its | peak memory [GiB] | error vs closed form |\n|---|---|---|---|---|---|---|---|---|---|---|\n")
    lines = []
    for r in rows:
        if "failed" in r:
            lines.append(f"| {r['element']} | | {r.get('target', '')} | {r['backend']} | failed: {r['failed']} "
                         "| | | | | | |")
            continue
        g = r["gmres_iterations"]
        its = ("/".join(str(i) for i in g) if len(g) <= 3 else f"{min(g)}-{max(g)} over {len(g)} solves") if g else "-"
        cells = f"{r['cells']} + {r['interfaces']} interfaces" if r.get("interfaces") else str(r["cells"])
        lines.append(f"| {r['element']} | {cells} | {r['dofs']} | {r['backend']} | {r['setup_s']:.2f} | "
                     f"{r['assembly_s']:.2f} | {r['solve_s']:.2f} | {r['factorizations']} | {its} | "
                     f"{r['peak_gib']:.2f} | {r['error']:.1e} |")
    return head + "\n".join(lines) + "\n"


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--sizes", type=float, nargs="+", default=[1e4, 1e5, 3e5, 1e6])
    p.add_argument("--elements", nargs="+", default=["hex8", "tet4"])
    p.add_argument("--backends", nargs="+", default=["pardiso", "gmres-amg"])
    p.add_argument("--timeout", type=float, default=1800.0)
    p.add_argument("--quick", action="store_true")
    p.add_argument("--problem", choices=["elastic", "plastic", "joints-ep", "joints-rp", "joints-rp-nested"], default="elastic")
    p.add_argument("--max-direct", type=float, default=float("inf"),
                   help="run pardiso only up to this many target dofs (its 3D factorization grows fastest)")
    p.add_argument("--child", nargs=4, metavar=("ELEMENT", "N", "BACKEND", "PROBLEM"))
    args = p.parse_args()
    if args.child:
        with tempfile.TemporaryDirectory() as tmp:
            print(json.dumps(child_run(args.child[0], int(args.child[1]), args.child[2], Path(tmp), args.child[3])))
        return
    sizes = [1e4] if args.quick else args.sizes
    info = machine()
    rows: list[dict] = []
    for element in args.elements:
        for size in sizes:
            for backend in args.backends:
                if backend == "pardiso" and size > args.max_direct:
                    continue
                r = child(["--child", element, str(cells_for(size, args.problem)), backend, args.problem], args.timeout)
                r.setdefault("element", element)
                r.setdefault("backend", backend)
                r["target"] = size
                rows.append(r)
                print(json.dumps(r), flush=True)
                if not args.quick:
                    suffix = "" if args.problem == "elastic" else f"_{args.problem}"
                    out = HERE / "results" / f"scaling_3d{suffix}.json"
                    out.write_text(json.dumps({"machine": info, "rows": rows}, indent=1))
                    text = (HERE / "README.md").read_text()
                    tag = "scaling-3d" + suffix.replace("_", "-")
                    a, b = f"<!-- {tag}-table:start -->\n", f"<!-- {tag}-table:end -->"
                    if a in text and b in text:
                        i, j = text.index(a) + len(a), text.index(b)
                        (HERE / "README.md").write_text(text[:i] + table(rows, info) + text[j:])
    print(table(rows, info))


if __name__ == "__main__":
    main()
