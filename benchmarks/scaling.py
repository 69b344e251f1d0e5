"""Scaling of the grains (EP CSE) and band (EDE) problems from 1e4 to 2e6 dofs.

One command (``python benchmarks/scaling.py``, ``make scaling``): for each problem and size, a
fresh Python process builds the example case with a finer mesh, runs its first load steps
(confinement and the first axial steps, chosen so that the interfaces yield / the band forms
at every size: see ``STEPS``) and records the set-up (mesh generation, build, CSR pattern), the
time per assembly call split into element kernels (the groups' ``evaluate``: traction laws,
return maps, B^T C B), scatter into CSR and the rest (copy of the constant bulk values, the
sparse product, Python), the linear solve (factorize + solve as the engine times it) per Newton
iteration, Newton iterations per step and the process's peak memory. Each process first runs a
small warm-up of the same problem (Numba kernels compiled or loaded from the cache). With
``--profile`` the timed run is also under cProfile; the top functions go to
``results/profile_<problem>_<dofs>.txt``.

Results: ``results/scaling.json`` and the table in ``benchmarks/README.md``.
Options: ``--problems grains band``, ``--sizes 1e4 1e5 1e6 2e6`` (target dofs), ``--steps``.
"""

from __future__ import annotations

import argparse
import contextlib
import cProfile
import io
import json
import os
import pstats
import resource
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))
from run import machine, replace_table, timing  # noqa: E402

SIZES = [1e4, 1e5, 1e6, 2e6]
W, H = 0.04, 0.08
# axial load steps of the short runs (after the confinement step); the loading is the example's
# with larger steps so that the first steps already reach the nonlinear response at every size
STEPS = {"grains": 2, "band": 2}
AXIAL = {  # (axial displacement [m], axial steps it is divided into): per-step increment
    "grains": (2.0e-3, 8),  # 0.25 mm per step: interfaces open/slide, matrix yields from step 2
    "band": (3.6e-3, 8),  # 0.45 mm per step: the bulk yields in step 1, the band localizes in step 3
}


def case_for(problem: str, dofs: float):
    """The example case with its mesh scaled to about ``dofs`` unknowns and the short loading."""
    from rockfrac.case.schema import load_case

    case = load_case(ROOT / "examples" / problem / f"{problem}.toml")
    if problem == "band":  # dofs = 2 (nx + 1)(ny + 1), ny = 2 nx
        nx = max(4, int(round(np.sqrt(dofs / 4.0))))
        mesh = case.mesh.model_copy(update={"nx": nx, "ny": 2 * nx})
    else:  # Gmsh quads of size h: ~1.1 W H / h^2 cells and ~2.1 dofs per cell on fine meshes (nodes,
        # split interface nodes, multipliers; measured at h = 0.32 mm; coarser meshes have relatively
        # more cells round the grains); the 40 grains stay as they are at every size
        mesh = case.mesh.model_copy(update={"element_size": float(np.sqrt(2.31 * W * H / dofs))})
    disp, steps = AXIAL[problem]
    loading = case.loading.model_copy(update={"axial_displacement": disp, "axial_steps": steps})
    out = case.output.model_copy(update={"vtk": False, "points": False, "checkpoint_every": 0})
    solver = case.solver.model_copy(update={"linear": "auto"})
    return case.model_copy(update={"mesh": mesh, "loading": loading, "output": out, "solver": solver})


def measure(problem: str, dofs: float, steps: int, profile: bool = False) -> dict:
    """Build and run one size in this process; set-up, assembly split, solve, Newton its per step."""
    import rockfrac.case.build as build_module
    import rockfrac.model as model_module
    from rockfrac.elements.cse_groups import CohesiveEP, CohesiveRP
    from rockfrac.elements.ede import EmbeddedDruckerPrager
    from rockfrac.elements.plastic_solid import DruckerPragerSolid
    from rockfrac.fem.assembly import Pattern
    from rockfrac.runner import history_row
    from rockfrac.solve import stepping
    from rockfrac.solve.linear import make_solver
    from rockfrac.solve.stepping import StopRun

    case = case_for(problem, dofs)
    setup: dict = {}
    with (timing(build_module, "make_mesh", setup, "mesh"), timing(Pattern, "build", setup, "pattern")):
        t0 = time.perf_counter()
        built = build_module.build(case)
        setup["total"] = time.perf_counter() - t0
    model = built.model
    stats = {"assembly": 0.0, "solve": 0.0, "iterations": 0, "assemblies": 0}
    parts: dict = {}
    rows: list[dict] = []
    from rockfrac.solve.newton import NewtonOptions
    from rockfrac.solve.stepping import SteppingOptions

    sol = case.solver
    newton = NewtonOptions(sol.max_iterations, sol.tol_residual, sol.tol_energy,
                           force_scale=1e-6 * max(m.E for m in case.material_list) * case.mesh.width)
    options = SteppingOptions(cutback=sol.cutback, min_step=sol.min_step)
    t_step = [time.perf_counter()]

    def on_step(info) -> None:
        row = history_row(built, info, None)
        now = time.perf_counter()
        keep = ("step", "stage", "u_axial", "F_axial", "newton_iterations", "cutbacks", "control",
                "bulk_plastic", "n_localized")
        r = {k: row[k] for k in keep if k in row}
        r["wall_s"] = now - t_step[0]
        t_step[0] = now
        for g in built.cohesives:
            r["cse_plastic"] = r.get("cse_plastic", 0) + int(np.sum(g.state[:, 7] == 1.0))
            r["cse_points"] = r.get("cse_points", 0) + int(g.points.n)
        rows.append(r)
        if sum(1 for x in rows if x["stage"].startswith("axial")) >= steps:
            raise StopRun(f"{steps} axial steps")

    original = stepping.newton_step

    def timed(*args, **kwargs):
        res = original(*args, **kwargs)
        stats["assembly"] += res.time_assembly
        stats["solve"] += res.time_solve
        stats["iterations"] += res.iterations
        stats["assemblies"] += len(res.residuals)
        return res

    prof = cProfile.Profile() if profile else None
    with contextlib.ExitStack() as stack:
        for cls, key in ((DruckerPragerSolid, "kernels"), (EmbeddedDruckerPrager, "kernels"),
                         (CohesiveRP, "kernels"), (CohesiveEP, "kernels")):
            if "evaluate" in vars(cls):
                stack.enter_context(timing(cls, "evaluate", parts, key))
        stack.enter_context(timing(model_module, "scatter_matrix", parts, "scatter"))
        stack.enter_context(timing(model_module, "scatter_vector", parts, "scatter"))
        stack.enter_context(timing(type(model), "commit", parts, "commit"))
        stack.enter_context(timing(type(model), "assemble", parts, "assemble"))
        if hasattr(type(model), "event"):
            stack.enter_context(timing(type(model), "event", parts, "event"))
        stepping.newton_step = timed
        stack.callback(setattr, stepping, "newton_step", original)
        t0 = time.perf_counter()
        if prof is not None:
            prof.enable()
        result = stepping.run_stages(model, built.stages, make_solver(sol.linear), newton, options, on_step)
        if prof is not None:
            prof.disable()
        wall = time.perf_counter() - t0
    n_asm = max(parts.get("assemble_n", 0), 1)  # every call (line-search trials included)
    its = max(stats["iterations"], 1)
    n_el = int(built.mesh.cells.shape[0])
    per_call = parts.get("assemble", 0.0) / n_asm
    kernels = parts.get("kernels", 0.0) / n_asm
    scatter = parts.get("scatter", 0.0) / n_asm
    axial = [r for r in rows if r["stage"].startswith("axial")]
    out = {
        "problem": problem, "target_dofs": dofs, "dofs": int(model.n_dofs), "elements": n_el,
        "nnz": int(model.pattern.nnz), "mesh": {k: v for k, v in case.mesh.model_dump().items() if v is not None},
        "setup_s": setup["total"], "setup_mesh_s": setup.get("mesh"), "setup_pattern_s": setup.get("pattern"),
        "steps": len(rows), "axial_steps": len(axial), "stop": result.message,
        "newton_iterations": stats["iterations"], "assemblies": parts.get("assemble_n", 0),
        "newton_per_axial_step": float(np.mean([r["newton_iterations"] for r in axial])) if axial else None,
        "assembly_per_call_s": per_call, "kernels_per_call_s": kernels, "scatter_per_call_s": scatter,
        "rest_per_call_s": per_call - kernels - scatter, "assembly_rate_elements_s": n_el / per_call,
        "solve_per_iteration_s": stats["solve"] / its,
        "commit_and_event_per_step_s": (parts.get("commit", 0.0) + parts.get("event", 0.0)) / max(len(rows), 1),
        "wall_s": wall, "history": rows,
    }
    if prof is not None:
        s = io.StringIO()
        pstats.Stats(prof, stream=s).sort_stats("tottime").print_stats(25)
        name = f"profile_{problem}_{out['dofs']}.txt"
        (HERE / "results").mkdir(exist_ok=True)
        (HERE / "results" / name).write_text(s.getvalue())
        out["profile"] = name
    return out


def run_one(problem: str, dofs: float, steps: int, profile: bool) -> dict:
    """One size in this process after a small untimed warm-up of the same problem."""
    measure(problem, 2e3, 2)
    r = measure(problem, dofs, steps, profile)
    r["peak_rss_gib"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20
    r["load"] = os.getloadavg()
    return r


def run_size(problem: str, dofs: float, steps: int, profile: bool) -> dict:
    """One size in a fresh Python process."""
    cmd = [sys.executable, str(Path(__file__).resolve()), "--one", problem, str(dofs), "--steps", str(steps)]
    if profile:
        cmd.append("--profile")
    load = os.getloadavg()
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, check=False, stdout=subprocess.PIPE, text=True)
    lines = proc.stdout.strip().splitlines()
    if proc.returncode != 0 or not lines:
        return {"problem": problem, "target_dofs": dofs, "failed": f"exit status {proc.returncode}",
                "process_wall_s": time.perf_counter() - t0, "load_before": load}
    r = json.loads(lines[-1])
    r["process_wall_s"] = time.perf_counter() - t0
    r["load_before"] = load
    return r


def exponent(results: list[dict]) -> float | None:
    """Slope of log(assembly per call) against log(elements)."""
    ok = [r for r in results if "failed" not in r]
    if len(ok) < 2:
        return None
    return float(np.polyfit(np.log([r["elements"] for r in ok]), np.log([r["assembly_per_call_s"] for r in ok]), 1)[0])


def table_lines(results: list[dict], info: dict) -> list[str]:
    lines = [f"Machine: {info['cpu']}, {info['cores']} cores, {info['memory']}; Python {info['python']}, "
             f"NumPy {info['numpy']}, SciPy {info['scipy']}, Numba {info['numba']}; {info['date']}; "
             f"linear solver: auto (pypardiso {info.get('pypardiso')}, MKL {info.get('mkl')}).", "",
             "| problem | dofs | elements | steps (axial) | Newton its / axial step | set-up [s] | of which mesh [s] "
             "| of which pattern [s] | assembly / call [s] | kernels [s] | scatter [s] | rest [s] | assembly rate "
             "[elements/s] | solve / it [s] | peak memory [GiB] | load (1 min) start / end |",
             "|---" * 16 + "|"]
    for r in results:
        if "failed" in r:
            lines.append(f"| {r['problem']} | ~{r['target_dofs']:.0e} | | failed: {r['failed']} |" + " |" * 12)
            continue
        lines.append(
            f"| {r['problem']} | {r['dofs']} | {r['elements']} | {r['steps']} ({r['axial_steps']}) | "
            f"{r['newton_per_axial_step']:.1f} | {r['setup_s']:.1f} | {r['setup_mesh_s']:.1f} | "
            f"{r['setup_pattern_s']:.1f} | {r['assembly_per_call_s']:.4f} | {r['kernels_per_call_s']:.4f} | "
            f"{r['scatter_per_call_s']:.4f} | {r['rest_per_call_s']:.4f} | {r['assembly_rate_elements_s']:.3g} | "
            f"{r['solve_per_iteration_s']:.3f} | {r['peak_rss_gib']:.2f} | "
            f"{r['load_before'][0]:.1f} / {r['load'][0]:.1f} |")
    lines.append("")
    for problem in sorted({r["problem"] for r in results}):
        e = exponent([r for r in results if r["problem"] == problem])
        if e is not None:
            lines.append(f"- {problem}: assembly time per call against elements, log-log exponent {e:.2f}.")
    return lines


def write_table(results: list[dict], info: dict) -> None:
    replace_table("scaling-table", table_lines(results, info))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--problems", nargs="+", default=["band", "grains"])
    ap.add_argument("--sizes", type=float, nargs="+", default=SIZES)
    ap.add_argument("--steps", type=int, default=None, help="axial steps per run (default: STEPS)")
    ap.add_argument("--profile", action="store_true", help="cProfile the timed runs")
    ap.add_argument("--no-save", action="store_true")
    ap.add_argument("--one", nargs=2, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.one:
        problem, dofs = args.one[0], float(args.one[1])
        print(json.dumps(run_one(problem, dofs, args.steps or STEPS[problem], args.profile)))
        return
    out = HERE / "results" / "scaling.json"
    old = json.loads(out.read_text())["results"] if out.exists() else []
    results = []
    for dofs in sorted(args.sizes):
        for problem in args.problems:
            r = run_size(problem, dofs, args.steps or STEPS[problem], args.profile)
            results.append(r)
            print(json.dumps({k: v for k, v in r.items() if k != "history"}), flush=True)
            if not args.no_save:  # merge: a size re-run replaces its old entry
                keep = [o for o in old if (o["problem"], o["target_dofs"]) not in
                        {(x["problem"], x["target_dofs"]) for x in results}]
                merged = sorted(keep + results, key=lambda x: (x["problem"], x["target_dofs"]))
                info = machine()
                out.parent.mkdir(exist_ok=True)
                out.write_text(json.dumps({"machine": info, "results": merged}, indent=1))
                write_table(merged, info)


if __name__ == "__main__":
    main()
