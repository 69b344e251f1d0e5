"""Engine benchmark: N x N quads with a cohesive line across, loaded past the peak.

One command (``make bench`` or ``python benchmarks/run.py``): for each mesh size, runs the
paper's specimen meshed with N x N bilinear quads (N/2 layers in each block) and an EP CSE
across it, confinement then axial loading under path control past the peak, and records per
Newton iteration the time in assembly (constitutive updates, element kernels, scatter into
CSR) and in the linear solve, the set-up time and the peak memory, together with the machine.
Each size runs in its own process (its peak memory is its own), after a small warm-up run in
that process that compiles or loads the Numba kernels outside the timings. Results go to
``benchmarks/results/engine.json`` and the table in ``benchmarks/README.md``.

Options: ``--sizes 22 70 224 708 1000`` (N values), ``--quick`` (the two smallest),
``--short-from 1000`` (sizes from this N on stop just past the peak), ``--solver``,

``--quick`` only prints; the full run rewrites ``results/engine.json`` and the README table.
"""

from __future__ import annotations

import argparse
import contextlib
import inspect
import json
import os
import platform
import re
import resource
import subprocess
import sys
import time
from importlib import metadata
from pathlib import Path

import numpy as np

HERE = Path(__file__).parent
FULL_STEPS = 6  # axial steps of a full run: a load step, the limit point, then path steps past it
SHORT_STEPS = 3  # the fewest that get past the peak: a load step, the peak step, one softening step
MAX_ITERATIONS = 8  # a load step that meets the limit point gives up after this many (default 25)
WARMUP_N = 8


def machine() -> dict:
    """What this ran on: CPU model, cores, memory, library versions."""
    import numba
    import scipy

    cpu = "unknown"
    try:
        text = Path("/proc/cpuinfo").read_text()
        cpu = re.search(r"model name\s*:\s*(.*)", text).group(1)
    except (OSError, AttributeError):
        pass
    mem = "unknown"
    try:
        kb = int(re.search(r"MemTotal:\s*(\d+)", Path("/proc/meminfo").read_text()).group(1))
        mem = f"{kb / 2**20:.1f} GiB"
    except (OSError, AttributeError):
        pass
    extras = {}
    for name in ("pypardiso", "mkl"):
        try:
            extras[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            extras[name] = None
    return {
        "cpu": cpu, "cores": os.cpu_count(), "memory": mem, "python": platform.python_version(),
        "numpy": np.__version__, "scipy": scipy.__version__, "numba": numba.__version__, **extras,
        "date": time.strftime("%Y-%m-%d"),
    }


def case_for(n: int, solver: str, axial_steps: int = FULL_STEPS) -> dict:
    """Paper specimen, N across, N/2 layers per block, EP CSE with Table 1's law.

    Axial loading: one load-controlled step to a third of 1 mm (elastic), a load-controlled step
    that meets the limit point and fails (after ``MAX_ITERATIONS``), then path-controlled steps
    of 5e-5 m mean crack jump, ``axial_steps`` converged axial steps in all.
    """
    return {
        "title": f"benchmark N={n}",
        "mesh": {"nx": n, "ny": max(1, n // 2), "crack_angle": 1.0471975511965976},
        "bulk": {"E": 1.5e7, "nu": 0.3},
        "cohesive": {
            "form": "ep", "kn": 1e9, "kt": 1e9, "GfI": 1e4, "GfII": 1e4, "chi_p": 15680.0,
            "chi_r": 0.0, "c_p": 9053.0, "c_r": 0.0, "phi_p": 0.5236, "phi_r": 0.0, "psi_p": 0.087,
            "alpha_chi": 2e3, "alpha_c": 2e3, "alpha_phi": 9e2, "alpha_psi": 9e2,
        },
        "loading": {"confinement": 2e4, "confinement_steps": 1, "axial_displacement": 1e-3,
                    "axial_steps": 3, "control": "path", "path_increment": 5e-5,
                    "max_steps": axial_steps},
        "output": {"points": False},
        "solver": {"linear": solver, "max_iterations": MAX_ITERATIONS},
    }


@contextlib.contextmanager
def timing(owner, name: str, sink: dict, key: str):
    """Accumulate in ``sink[key]`` the seconds spent in ``owner.name`` while the block runs."""
    saved = inspect.getattr_static(owner, name, None)
    if saved is None:  # renamed in the engine: time nothing rather than fail
        yield
        return
    original = getattr(owner, name)

    def wrapper(*args, **kwargs):
        sink[key + "_n"] = sink.get(key + "_n", 0) + 1
        t0 = time.perf_counter()
        try:
            return original(*args, **kwargs)
        finally:
            sink[key] = sink.get(key, 0.0) + time.perf_counter() - t0

    setattr(owner, name, wrapper)
    try:
        yield
    finally:
        setattr(owner, name, saved)


def newton_options(case):
    """Newton and stepping options of a case, as ``rockfrac run`` sets them."""
    from rockfrac.solve.newton import NewtonOptions
    from rockfrac.solve.stepping import SteppingOptions

    sol = case.solver
    newton = NewtonOptions(sol.max_iterations, sol.tol_residual, sol.tol_energy,
                           force_scale=1e-6 * max(m.E for m in case.material_list) * case.mesh.width)
    return newton, SteppingOptions(cutback=sol.cutback, min_step=sol.min_step)


def measure(n: int, solver: str, axial_steps: int) -> dict:
    """Build and run one size in this process; set-up, per-iteration times and the steps run."""
    import rockfrac.case.build as build_module
    from rockfrac.case.schema import parse_case
    from rockfrac.fem.assembly import Pattern
    from rockfrac.runner import history_row
    from rockfrac.solve import stepping
    from rockfrac.solve.linear import make_solver

    case = parse_case(case_for(n, solver, axial_steps), f"benchmark N={n}")
    setup: dict = {}
    with (timing(build_module, "make_mesh", setup, "mesh"),
          timing(build_module, "make_bulk", setup, "bulk"),
          timing(Pattern, "build", setup, "pattern")):
        t0 = time.perf_counter()
        built = build_module.build(case)
        setup["total"] = time.perf_counter() - t0
    stats = {"assembly": 0.0, "solve": 0.0, "iterations": 0, "assemblies": 0, "attempts": 0}
    parts: dict = {}  # seconds in the cohesive group's evaluate and in starting solver objects
    steps: list[dict] = []

    def on_step(info) -> None:
        row = history_row(built, info, None)
        steps.append({k: row[k] for k in ("step", "stage", "control", "u_axial", "F_axial",
                                          "newton_iterations")})

    original = stepping.newton_step

    def timed(*args, **kwargs):  # every Newton solve, failed attempts included
        res = original(*args, **kwargs)
        stats["assembly"] += res.time_assembly
        stats["solve"] += res.time_solve
        stats["iterations"] += res.iterations  # = factorizations
        stats["assemblies"] += len(res.residuals)
        stats["attempts"] += 1
        return res

    newton, stepping_options = newton_options(built.case)
    with contextlib.ExitStack() as stack:
        stack.enter_context(timing(type(built.cohesive), "evaluate", parts, "cohesive"))
        if solver == "pardiso":
            import pypardiso

            start = timing(pypardiso.PyPardisoSolver, "__init__", parts, "solver_start")
            stack.enter_context(start)
        stepping.newton_step = timed
        stack.callback(setattr, stepping, "newton_step", original)
        t0 = time.perf_counter()
        result = stepping.run_stages(built.model, built.stages, make_solver(solver), newton,
                                     stepping_options, on_step)
        wall = time.perf_counter() - t0
    axial = [s["F_axial"] for s in steps if s["stage"].startswith("axial")]
    peak = int(np.argmax(axial)) if axial else -1
    its = max(stats["iterations"], 1)
    return {
        "N": n, "solver": solver, "dofs": int(built.model.n_dofs),
        "elements": int(built.mesh.cells.shape[0]), "nnz": int(built.model.pattern.nnz),
        "setup_s": setup["total"], "setup_mesh_s": setup.get("mesh"),
        "setup_bulk_s": setup.get("bulk"),
        "setup_pattern_s": setup.get("pattern"), "axial_steps_requested": axial_steps,
        "steps": result.steps, "stop": result.message, "newton_iterations": stats["iterations"],
        "assemblies": stats["assemblies"], "newton_calls": stats["attempts"],
        "assembly_total_s": stats["assembly"], "solve_total_s": stats["solve"],
        "assembly_per_call_s": stats["assembly"] / max(stats["assemblies"], 1),
        "solve_per_iteration_s": stats["solve"] / its,
        "cohesive_per_call_s": parts.get("cohesive", 0.0) / max(stats["assemblies"], 1),
        "solver_start_per_iteration_s": parts.get("solver_start", 0.0) / its,
        "peak_force": max(axial) if axial else None, "final_force": axial[-1] if axial else None,
        "past_peak": bool(axial) and 0 <= peak < len(axial) - 1 and axial[-1] < axial[peak],
        "wall_s": wall, "history": steps,
    }


def run_one(n: int, solver: str, axial_steps: int) -> dict:
    """One size in this process, after an untimed warm-up; adds the process's peak memory."""
    measure(WARMUP_N, solver, FULL_STEPS)  # compile / load the Numba kernels outside the timings
    r = measure(n, solver, axial_steps)
    r["peak_rss_gib"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20  # KiB on Linux
    return r


def run_size(n: int, solver: str, axial_steps: int) -> dict:
    """One size in a fresh Python process (independent memory and timings)."""
    cmd = [sys.executable, str(Path(__file__).resolve()), "--one", str(n), "--solver", solver,
           "--axial-steps", str(axial_steps)]
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, check=False, stdout=subprocess.PIPE, text=True)
    wall = time.perf_counter() - t0
    lines = proc.stdout.strip().splitlines()
    if proc.returncode != 0 or not lines:
        return {"N": n, "solver": solver, "failed": f"exit status {proc.returncode}",
                "process_wall_s": wall}
    r = json.loads(lines[-1])
    r["process_wall_s"] = wall
    return r


def exponent(results: list[dict], min_dofs: int = 0) -> float | None:
    """Slope of log(assembly per call) against log(elements), least squares."""
    ok = [r for r in results if "failed" not in r and r["dofs"] >= min_dofs]
    if len(ok) < 2:
        return None
    x = np.log([r["elements"] for r in ok])
    y = np.log([r["assembly_per_call_s"] for r in ok])
    return float(np.polyfit(x, y, 1)[0])


def describe_run(r: dict) -> str:
    """What was run: converged steps (confinement included), full run or just past the peak."""
    kind = "full" if r["axial_steps_requested"] >= FULL_STEPS else "to just past the peak"
    return f"{r['steps']} ({kind})"


def table_lines(results: list[dict], info: dict, total_s: float) -> list[str]:
    """Machine line, the table and the fit of assembly time against elements, as Markdown."""
    ok = [r for r in results if "failed" not in r]
    solver = results[0]["solver"]
    if solver == "pardiso":
        solver += f" (pypardiso {info.get('pypardiso')}, MKL {info.get('mkl')})"
    lines = [
        f"Machine: {info['cpu']}, {info['cores']} cores, {info['memory']}; "
        f"Python {info['python']}, NumPy {info['numpy']}, SciPy {info['scipy']}, "
        f"Numba {info['numba']}; {info['date']}; "
        f"linear solver: {solver}"
        + ".",
        "",
        ("| N | dofs | elements | steps run | Newton its (assemblies) | assembly / call [s] | "
         "of which cohesive [s] | assembly per element [us] | solve / it [s] | of which solver "
         "start-up [s] | set-up [s] | of which pattern [s] | peak memory [GiB] | "
         "past peak (peak -> last F, N/m) |"),
        "|---" * 14 + "|",
    ]
    for r in results:
        if "failed" in r:
            lines.append(f"| {r['N']} | | | failed: {r['failed']} |" + " |" * 10)
            continue
        pattern = f"{r['setup_pattern_s']:.2f}" if r.get("setup_pattern_s") is not None else "n/a"
        lines.append(
            f"| {r['N']} | {r['dofs']} | {r['elements']} | {describe_run(r)} | "
            f"{r['newton_iterations']} ({r['assemblies']}) | {r['assembly_per_call_s']:.4f} | "
            f"{r['cohesive_per_call_s']:.4f} | "
            f"{1e6 * r['assembly_per_call_s'] / r['elements']:.3f} | "
            f"{r['solve_per_iteration_s']:.3f} | {r['solver_start_per_iteration_s']:.3f} | "
            f"{r['setup_s']:.2f} | {pattern} | {r['peak_rss_gib']:.2f} | "
            f"{'yes' if r['past_peak'] else 'no'} "
            f"({r['peak_force']:.0f} -> {r['final_force']:.0f}) |"
        )
    e_all, e_big = exponent(results), exponent(results, 100_000)
    fit = "Assembly time per call against elements, log-log least squares: exponent "
    fit += f"{e_all:.2f} over all sizes" if e_all is not None else "n/a"
    if e_big is not None:
        n_big = len([r for r in ok if r["dofs"] >= 100_000])
        fit += f", {e_big:.2f} over the {n_big} sizes from 1e5 dofs on"
    lines += ["", fit + f". Total wall time of the benchmark: {total_s / 60:.1f} min."]
    return lines


def markdown_table(headers: list[str], rows: list[list]) -> list[str]:
    """The lines of a Markdown table: a header row, the rule, one line per row (cells as given)."""
    return ["| " + " | ".join(headers) + " |", "|" + "---|" * len(headers),
            *("| " + " | ".join(str(c) for c in row) + " |" for row in rows)]


def publish(name: str, record: dict, lines: list[str], footer: str | None = None) -> None:
    """Finish a benchmark: the load average at its end into ``record`` (which holds ``machine`` and
    ``load_start``), ``results/<name>.json``, and the table ``lines`` with a line naming the machine
    and the load (or ``footer``, for a table whose rows carry their own), printed and put between the
    ``<name>-table`` markers of README.md (underscores as dashes)."""
    record["load_end"] = os.getloadavg()
    (HERE / "results").mkdir(exist_ok=True)
    (HERE / "results" / f"{name}.json").write_text(json.dumps(record, indent=1))
    m, load = record["machine"], (record["load_start"][0], record["load_end"][0])
    lines = lines + ["", footer or f"{m['cpu']}, {m['cores']} cores; load average {load[0]:.2f} at the start, "
                     f"{load[1]:.2f} at the end."]
    print("\n".join(lines))
    replace_table(name.replace("_", "-") + "-table", lines)


def replace_table(name: str, lines: list[str]) -> bool:
    """Put ``lines`` between the ``<!-- name:start -->`` and ``<!-- name:end -->`` markers of
    README.md; False (nothing written) if the markers are missing."""
    readme = HERE / "README.md"
    text = readme.read_text()
    start, end = f"<!-- {name}:start -->", f"<!-- {name}:end -->"
    if start not in text or end not in text:
        return False
    head, rest = text.split(start)
    _, tail = rest.split(end)
    readme.write_text(head + start + "\n" + "\n".join(lines) + "\n" + end + tail)
    return True


def write_table(results: list[dict], info: dict, total_s: float) -> None:
    replace_table("engine-table", table_lines(results, info, total_s))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[22, 70, 224, 708, 1000])
    ap.add_argument("--quick", action="store_true", help="only the two smallest sizes")
    ap.add_argument("--short-from", type=int, default=1000,
                    help=f"sizes N >= this run {SHORT_STEPS} axial steps (just past the peak), "
                         f"the others {FULL_STEPS}")
    ap.add_argument("--one", type=int, help=argparse.SUPPRESS)  # one size, in this process
    ap.add_argument("--axial-steps", type=int, default=FULL_STEPS, help=argparse.SUPPRESS)
    from rockfrac.solve.linear import available

    default = "pardiso" if "pardiso" in available() else "superlu"
    ap.add_argument("--solver", default=default, help=f"linear solver (default here: {default})")
    args = ap.parse_args()
    if args.one is not None:
        print(json.dumps(run_one(args.one, args.solver, args.axial_steps)))
        return
    sizes = sorted(args.sizes)[:2] if args.quick else args.sizes
    out = HERE / "results"
    out.mkdir(exist_ok=True)
    info = machine()
    t0 = time.perf_counter()
    results = []
    for n in sizes:
        steps = SHORT_STEPS if n >= args.short_from else FULL_STEPS
        r = run_size(n, args.solver, steps)
        results.append(r)
        print(json.dumps({k: v for k, v in r.items() if k != "history"}), flush=True)
    total = time.perf_counter() - t0
    if args.quick:  # a smoke test: leave the recorded results alone
        return
    (out / "engine.json").write_text(json.dumps({"machine": info, "total_wall_s": total,
                                                 "results": results}, indent=1))
    write_table(results, info, total)


if __name__ == "__main__":
    main()
