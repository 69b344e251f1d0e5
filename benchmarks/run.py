"""Engine benchmark: N x N quads with a cohesive line across, loaded past the peak.

One command (``make bench`` or ``python benchmarks/run.py``): for each mesh size, runs the
paper's specimen meshed with N x N bilinear quads (N/2 layers in each block) and an EP CSE
across it, confinement then axial loading under path control past the peak, and records per
Newton iteration the time in assembly (constitutive updates, element kernels, scatter into
CSR) and in the linear solve, together with the machine. Results go to
``benchmarks/results/engine.json`` and the table in ``benchmarks/README.md``.

Options: ``--sizes 22 70 224 708`` (N values), ``--quick`` (the two smallest).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import re
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).parent


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
    return {
        "cpu": cpu, "cores": os.cpu_count(), "memory": mem, "python": platform.python_version(),
        "numpy": np.__version__, "scipy": scipy.__version__, "numba": numba.__version__,
        "date": time.strftime("%Y-%m-%d"),
    }


def case_for(n: int, solver: str) -> dict:
    """Paper specimen, N across, N/2 layers per block, EP CSE with Table 1's law."""
    return {
        "title": f"benchmark N={n}",
        "mesh": {"nx": n, "ny": max(1, n // 2), "crack_angle": 1.0471975511965976},
        "bulk": {"E": 1.5e7, "nu": 0.3},
        "cohesive": {
            "form": "ep", "kn": 1e9, "kt": 1e9, "GfI": 1e4, "GfII": 1e4, "chi_p": 15680.0,
            "chi_r": 0.0, "c_p": 9053.0, "c_r": 0.0, "phi_p": 0.5236, "phi_r": 0.0, "psi_p": 0.087,
            "alpha_chi": 2e3, "alpha_c": 2e3, "alpha_phi": 9e2, "alpha_psi": 9e2,
        },
        # elastic up to ~90% of the peak in 2 steps, then path control past it
        "loading": {"confinement": 2e4, "confinement_steps": 1, "axial_displacement": 1e-3,
                    "axial_steps": 3, "control": "path", "path_increment": 5e-5, "max_steps": 6},
        "output": {"points": False},
        "solver": {"linear": solver},
    }


def run_size(n: int, out: Path, solver: str) -> dict:
    from rockfrac.case.build import build
    from rockfrac.case.schema import parse_case
    from rockfrac.run import run_case

    case = parse_case(case_for(n, solver), f"benchmark N={n}")
    t0 = time.perf_counter()
    built = build(case)
    t_setup = time.perf_counter() - t0
    stats = {"assembly": [], "solve": [], "iterations": []}
    import rockfrac.solve.stepping as stepping

    original = stepping.newton_step

    def timed(*args, **kwargs):
        res = original(*args, **kwargs)
        stats["assembly"].append(res.time_assembly)
        stats["solve"].append(res.time_solve)
        stats["iterations"].append(max(res.iterations, 1))
        return res

    stepping.newton_step = timed
    try:
        summary = run_case(case, out / f"N{n}")
    finally:
        stepping.newton_step = original
    from rockfrac.output.csvout import read_csv

    h = read_csv(out / f"N{n}" / "history.csv")
    iters = sum(stats["iterations"])
    return {
        "N": n, "solver": solver, "dofs": int(built.model.n_dofs), "elements": int(built.mesh.quads.shape[0]),
        "nnz": int(built.model.pattern.nnz), "setup_s": t_setup, "steps": summary.result.steps,
        "newton_iterations": iters,
        "assembly_per_iteration_s": sum(stats["assembly"]) / iters,
        "solve_per_iteration_s": sum(stats["solve"]) / iters,
        "peak_force": float(np.nanmax(h["F_axial"])), "final_force": float(h["F_axial"][-1]),
        "past_peak": bool(h["F_axial"][-1] < np.nanmax(h["F_axial"])),
        "wall_s": summary.wall_time,
    }


def write_table(results: list[dict], info: dict) -> None:
    lines = [
        f"Machine: {info['cpu']}, {info['cores']} cores, {info['memory']}; Python {info['python']}, "
        f"NumPy {info['numpy']}, SciPy {info['scipy']}, Numba {info['numba']}; {info['date']}; "
        f"linear solver: {results[0]['solver']}.",
        "",
        "| N | dofs | elements | Newton its | assembly / it [s] | solve / it [s] | assembly per element [us] | set-up [s] | past peak |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in results:
        lines.append(
            f"| {r['N']} | {r['dofs']} | {r['elements']} | {r['newton_iterations']} | "
            f"{r['assembly_per_iteration_s']:.4f} | {r['solve_per_iteration_s']:.4f} | "
            f"{1e6 * r['assembly_per_iteration_s'] / r['elements']:.3f} | {r['setup_s']:.2f} | "
            f"{'yes' if r['past_peak'] else 'no'} |"
        )
    readme = HERE / "README.md"
    text = readme.read_text()
    start, end = "<!-- engine-table:start -->", "<!-- engine-table:end -->"
    head, rest = text.split(start)
    _, tail = rest.split(end)
    readme.write_text(head + start + "\n" + "\n".join(lines) + "\n" + end + tail)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[22, 70, 224, 708])
    ap.add_argument("--quick", action="store_true", help="only the two smallest sizes")
    from rockfrac.solve.linear import available

    default = "pardiso" if "pardiso" in available() else "superlu"
    ap.add_argument("--solver", default=default, help=f"linear solver (default here: {default})")
    args = ap.parse_args()
    sizes = args.sizes[:2] if args.quick else args.sizes
    out = HERE / "results"
    out.mkdir(exist_ok=True)
    info = machine()
    run_size(8, out / "warmup", args.solver)  # compile the Numba kernels outside the timings
    results = []
    for n in sizes:
        r = run_size(n, out / "runs", args.solver)
        results.append(r)
        print(json.dumps(r))
    (out / "engine.json").write_text(json.dumps({"machine": info, "results": results}, indent=1))
    if not args.quick:
        write_table(results, info)


if __name__ == "__main__":
    main()
