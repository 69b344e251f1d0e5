"""Linear solver benchmark: every backend on real tangents of the grains and band examples.

One command (``python benchmarks/solvers.py``): for each problem and size, one process runs the
example case (mesh scaled: ``element_size`` for the grains, ``nx, ny`` for the block; the grains' surfaces
made rigid-plastic, RP, whatever the example uses) a few load
steps into the plastic (grains: debonding interfaces and a yielding matrix; band: a yielding,
non-associative Drucker-Prager block at the onset of localization) and keeps the tangent and
right-hand side of one Newton iteration, with the Dirichlet rows applied as the engine does. Then
each backend runs in its own process on that system: factorize twice (the first includes the
analysis, where a backend reuses it per pattern; the second is what every later Newton iteration
pays), one solve; the relative residual |A x - b| / |b|, the distance to SuperLU's solution, and
the peak memory above the loaded matrix (``ru_maxrss``). Results go to
``benchmarks/results/solvers.json`` and the "Linear solvers" table in ``benchmarks/README.md``.

Options: ``--sizes 1e4 1e5 1e6`` (target dofs), ``--problems grains band``, ``--backends ...``,
``--timeout`` (seconds per backend process), ``--merge`` (keep the earlier results of the
problems and sizes not run now), ``--systems DIR`` (captured systems are kept there and reused),
``--quick`` (1e4 only, prints, writes nothing). A backend that fails, or takes more than 10 x the
fastest per iteration, is not run at the larger sizes. The JSON and the table are rewritten after
every system.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import resource
import subprocess
import sys
import tempfile
import time
import tomllib
from pathlib import Path

import numpy as np
import scipy.sparse as sp

HERE = Path(__file__).parent
ROOT = HERE.parent
# grains: up to ~1 mm the element size is set by the 12 quads per grain circle; below, dofs ~ h^-2
GRAINS_FINE = (0.0005, 32000)  # element_size [m] and about the dofs it gives
CAPTURE_AFTER = {"grains": 10, "band": 12}  # the tangent of this Newton solve is kept (a few load steps in)


class Captured(Exception):
    """Raised (not a RuntimeError: Newton lets it through) once the wanted system is kept."""


def case_dict(problem: str, dofs: float) -> dict:
    """The example case with its mesh scaled to about ``dofs`` unknowns and coarse load steps."""
    d = tomllib.loads((ROOT / "examples" / problem / f"{problem}.toml").read_text())
    d.pop("output", None)
    if problem == "grains":
        d["cohesive"]["form"] = "rp"  # the saddle-point problem: rigid-plastic surfaces with multipliers
        d["cohesive"].pop("kn", None)
        d["cohesive"].pop("kt", None)
        if dofs > 2e4:  # else the example's own 2 mm (1.5e4 dofs)
            h, n = GRAINS_FINE
            d["mesh"]["element_size"] = h * math.sqrt(n / dofs)
        d["loading"]["axial_steps"] = 20  # 0.1 mm per step: interfaces yield in the first, the matrix in the second
    else:
        nx = max(4, round(math.sqrt(dofs / 4)))
        d["mesh"]["nx"], d["mesh"]["ny"] = nx, 2 * nx
        d["loading"]["axial_steps"] = 5  # 0.6 mm per step: plastic, localizing near 1.2 mm
    d["solver"] = {"linear": "auto"}
    return d


def capture(problem: str, dofs: float, folder: Path) -> dict:
    """Run the case until its CAPTURE_AFTER-th Newton solve; save that system to ``folder``."""
    from rockfrac.case.build import build
    from rockfrac.case.schema import parse_case
    from rockfrac.runner import history_row, point_rows
    from rockfrac.solve.linear import make_solver
    from rockfrac.solve.newton import NewtonOptions
    from rockfrac.solve.stepping import SteppingOptions, run_stages

    t0 = time.perf_counter()
    case = parse_case(case_dict(problem, dofs), f"{problem}.toml")
    built = build(case)
    t_build = time.perf_counter() - t0
    inner = make_solver("auto")
    state = {"solves": 0, "row": None}

    class Keeper:
        name = inner.name

        def begin_step(self) -> None:
            inner.begin_step()

        def notes(self) -> list[str]:
            return inner.notes()

        def factorize(self, a):
            state["solves"] += 1
            factor = inner.factorize(a)
            if state["solves"] < CAPTURE_AFTER[problem]:
                return factor
            # a step's first iteration may use an elastic (symmetric) predictor: wait for a real tangent
            if abs(a - a.T).max() <= 1e-10 * abs(a).max() and state["solves"] < CAPTURE_AFTER[problem] + 10:
                return factor
            kept = a.copy()

            class Keep:
                def solve(self, b):
                    sp.save_npz(folder / "a.npz", kept)
                    np.save(folder / "b.npy", b)
                    raise Captured

            return Keep()

    def on_step(info) -> None:
        state["row"] = history_row(built, info, point_rows(built, info.u))

    sol = case.solver
    newton = NewtonOptions(sol.max_iterations, sol.tol_residual, sol.tol_energy,
                           force_scale=1e-6 * max(m.E for m in case.material_list) * case.mesh.width)
    try:
        run_stages(built.model, built.stages, Keeper(), newton, SteppingOptions(), on_step)
        raise SystemExit(f"{problem}: the run ended before Newton solve {CAPTURE_AFTER[problem]}")
    except Captured:
        pass
    a = sp.load_npz(folder / "a.npz").tocsr()
    row = state["row"] or {}
    diag = a.diagonal()
    info = {
        "problem": problem, "target_dofs": dofs, "dofs": int(a.shape[0]), "nnz": int(a.nnz),
        "mesh": {k: case_dict(problem, dofs)["mesh"][k] for k in ("element_size", "nx", "ny") if k in case_dict(problem, dofs)["mesh"]},
        "newton_solve": state["solves"],
        "zero_diagonals": int(np.sum(diag == 0.0)),
        "asymmetry": float(abs(a - a.T).max() / abs(a).max()),
        "last_committed_step": {k: (float(v) if isinstance(v, (int, float, np.floating)) else str(v))
                                for k, v in row.items() if k in ("step", "u_axial", "F_axial", "n_plastic",
                                                                 "bulk_plastic", "n_localized")},
        "build_s": t_build, "capture_s": time.perf_counter() - t0,
    }
    (folder / "info.json").write_text(json.dumps(info))
    return info


def peak_gib() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20


def time_backend(name: str, folder: Path) -> dict:
    """Factorize twice and solve once with backend ``name`` on the saved system; save x."""
    from rockfrac.solve.linear import SolverFailed, make_solver

    a = sp.load_npz(folder / "a.npz").tocsr()
    b = np.load(folder / "b.npy")
    mem0 = peak_gib()
    solver = make_solver(name)
    out: dict = {"backend": name}
    try:
        t0 = time.perf_counter()
        factor = solver.factorize(a)
        first = time.perf_counter() - t0
        again = first  # nothing is reused: every iteration pays the first
        if name in ("pardiso", "mumps"):  # same pattern again: numeric factorization only
            t0 = time.perf_counter()
            factor = solver.factorize(a.copy())
            again = time.perf_counter() - t0
        t0 = time.perf_counter()
        x = factor.solve(b)
        solve = time.perf_counter() - t0
    except SolverFailed as err:
        out.update(failed=str(err), memory_gib=peak_gib() - mem0)
        return out
    out.update(first_factorization_s=first, factorization_s=again, solve_s=solve,
               analysis_s=max(first - again, 0.0) if name in ("pardiso", "mumps") else None,
               per_iteration_s=again + solve,
               residual=float(np.linalg.norm(a @ x - b) / np.linalg.norm(b)),
               memory_gib=peak_gib() - mem0, peak_gib=peak_gib())
    if name == "gmres-amg":
        out["gmres_iterations"] = factor.iterations
        out["analysis_s"] = None
    np.save(folder / f"x_{name}.npy", x)
    return out


def load_average() -> list[float]:
    return [round(v, 2) for v in os.getloadavg()]


def child(args: list[str], timeout: float) -> dict:
    """Run this script in a fresh process (own peak memory); its last stdout line is JSON."""
    t0 = time.perf_counter()
    try:
        p = subprocess.run([sys.executable, __file__, *args], capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return {"failed": f"not finished in {timeout:.0f} s (killed)"}
    if p.returncode != 0:
        return {"failed": (p.stderr.strip().splitlines() or ["exit code %d" % p.returncode])[-1]}
    out = json.loads(p.stdout.strip().splitlines()[-1])
    out["wall_s"] = time.perf_counter() - t0
    return out


def machine() -> dict:
    sys.path.insert(0, str(HERE))
    from run import machine as engine_machine  # the engine benchmark's record of the machine

    from importlib import metadata

    info = engine_machine()
    for name in ("python-mumps", "pyamg"):
        try:
            info[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            info[name] = None
    return info


def fmt(v, digits: int = 2) -> str:
    if v is None:
        return "-"
    if isinstance(v, float):
        return f"{v:.{digits}e}" if (v != 0 and (abs(v) < 1e-2 or abs(v) >= 1e4)) else f"{v:.{digits}f}"
    return str(v)


def table_lines(results: list[dict], info: dict, total_s: float) -> list[str]:
    lines = [f"Machine: {info['cpu']}, {info['cores']} cores, {info['memory']}; Python {info['python']}, "
             f"NumPy {info['numpy']}, SciPy {info['scipy']}, pypardiso {info['pypardiso']} (MKL {info['mkl']}), "
             f"python-mumps {info['python-mumps']}, pyamg {info['pyamg']}; {info['date']}. Total wall time "
             f"{total_s / 60:.1f} min.", "",
             "| problem | dofs | nnz | zero diag. | backend | load avg. (1 min) | analysis [s] | numeric "
             "factorization [s] | solve [s] | per Newton iteration [s] | first factorization [s] | residual "
             "| vs SuperLU | memory [GiB] |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in results:
        for t in r["backends"]:
            if "failed" in t:
                lines.append(f"| {r['problem']} | {r['dofs']} | {r['nnz']} | {r['zero_diagonals']} | {t['backend']} | "
                             f"{t['load'][0]} | failed: {t['failed'][:90]} | | | | | | | {fmt(t.get('memory_gib'))} |")
                continue
            lines.append(
                f"| {r['problem']} | {r['dofs']} | {r['nnz']} | {r['zero_diagonals']} | {t['backend']} | {t['load'][0]} | "
                f"{fmt(t['analysis_s'])} | {fmt(t['factorization_s'])} | {fmt(t['solve_s'])} | "
                f"{fmt(t['per_iteration_s'])} | {fmt(t['first_factorization_s'])} | {fmt(t['residual'])} | "
                f"{fmt(t.get('vs_superlu'))} | {fmt(t['memory_gib'])} |")
    return lines


def write_table(lines: list[str]) -> None:
    sys.path.insert(0, str(HERE))
    from run import replace_table

    replace_table("solvers-table", lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=float, nargs="+", default=[1e4, 1e5, 1e6])
    ap.add_argument("--problems", nargs="+", default=["grains", "band"])
    ap.add_argument("--backends", nargs="+", default=None)
    ap.add_argument("--timeout", type=float, default=600.0)
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--merge", action="store_true", help="keep earlier results of sizes not run now")
    ap.add_argument("--systems", default=str(Path(tempfile.gettempdir()) / "rockfrac-solver-systems"),
                    help="where the captured systems are kept (and reused when there)")
    ap.add_argument("--capture", nargs=3, metavar=("PROBLEM", "DOFS", "FOLDER"), help=argparse.SUPPRESS)
    ap.add_argument("--time", nargs=2, metavar=("BACKEND", "FOLDER"), help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.capture:
        print(json.dumps(capture(args.capture[0], float(args.capture[1]), Path(args.capture[2]))))
        return
    if args.time:
        print(json.dumps(time_backend(args.time[0], Path(args.time[1]))))
        return

    from rockfrac.solve.linear import available

    sizes = [1e4] if args.quick else args.sizes
    backends = args.backends or available()
    backends = sorted(backends, key=lambda n: n != "superlu")  # the reference first
    info = machine()
    path = HERE / "results" / "solvers.json"
    earlier = json.loads(path.read_text()) if (args.merge and path.exists()) else {"results": [], "total_wall_s": 0.0}
    results, t_start = [], time.perf_counter()
    given_up: dict[tuple[str, str], str] = {}  # (problem, backend) -> why it is not run at larger sizes
    for problem in args.problems:
        for dofs in sizes:
            folder = Path(args.systems) / f"{problem}-{dofs:.0e}"
            folder.mkdir(parents=True, exist_ok=True)
            if (folder / "info.json").exists():  # captured before: the same system again
                cap = json.loads((folder / "info.json").read_text())
            else:
                cap = child(["--capture", problem, repr(dofs), str(folder)], 3 * args.timeout)
            if "failed" in cap:
                print(f"{problem} {dofs:.0e}: capture failed: {cap['failed']}", flush=True)
                continue
            print(f"{problem}: {cap['dofs']} dofs, nnz {cap['nnz']}, captured in {cap['capture_s']:.1f} s, "
                  f"state {cap['last_committed_step']}", flush=True)
            cap["backends"] = []
            for name in backends:
                if (problem, name) in given_up:
                    cap["backends"].append({"backend": name, "load": load_average(),
                                            "failed": f"not run: {given_up[(problem, name)]}"})
                    continue
                load = load_average()
                t = child(["--time", name, str(folder)], args.timeout)
                t["backend"], t["load"] = name, load
                fastest = min((u["per_iteration_s"] for u in cap["backends"] if "per_iteration_s" in u),
                              default=None)
                if "failed" in t:
                    given_up[(problem, name)] = f"failed at {cap['dofs']} dofs"
                elif fastest is not None and t["per_iteration_s"] > 10 * fastest:
                    # 10 x the fastest here is past the timeout at 10 x the dofs: keeps the run short
                    given_up[(problem, name)] = f"{t['per_iteration_s'] / fastest:.0f} x the fastest at {cap['dofs']} dofs"
                if "failed" not in t and name != "superlu" and (folder / "x_superlu.npy").exists():
                    x, ref = np.load(folder / f"x_{name}.npy"), np.load(folder / "x_superlu.npy")
                    t["vs_superlu"] = float(np.abs(x - ref).max() / np.abs(ref).max())
                cap["backends"].append(t)
                print(f"  {name}: {json.dumps({k: v for k, v in t.items() if k != 'backend'})}", flush=True)
            results.append(cap)
            if not args.quick:  # after every system: an interrupted run keeps what it measured
                done = {(r["problem"], r["target_dofs"]) for r in results}
                kept = [r for r in earlier["results"] if (r["problem"], r["target_dofs"]) not in done]
                merged = sorted(kept + results, key=lambda r: (r["problem"] != "grains", r["dofs"]))
                total = earlier["total_wall_s"] + time.perf_counter() - t_start
                path.parent.mkdir(exist_ok=True)
                path.write_text(json.dumps({"machine": info, "total_wall_s": total, "results": merged}, indent=1))
                write_table(table_lines(merged, info, total))
    total = earlier["total_wall_s"] + time.perf_counter() - t_start
    print("\n".join(table_lines(results, info, total)))


if __name__ == "__main__":
    main()
