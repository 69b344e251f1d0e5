"""rockfrac against Akantu on the same cohesive problem, one command: ``make bench-peer``.

For each N: one Gmsh file of the N x N triangle block (peer_mesh), read by both codes; Akantu
(intrinsic cohesive_bilinear, static Newton) runs in its own virtualenv ``.venv-akantu``
(created with ``pip install akantu`` when missing, so rockfrac's ``.venv`` is never touched),
then rockfrac (EP CSE, ``linear = "auto"``, the trapezoidal work rule; again with one thread;
again with the paper's backward-Euler rule), each in its own process, one after the other. The
problem and its closed forms are in peer_problem. Prints the table; the full run also writes
``results/peer.json`` and the table in ``README.md``.

Options: ``--sizes 22 70 158 224`` (N, even), ``--quick`` (N = 22 only, print only),
``--profile N`` (cProfile rockfrac's default run at that N, 70 unless given; the top functions
go into the JSON),
``--refine K`` (K > 1: one more rockfrac run per size with K times as many steps, by the work rule
``--refine-rule``, trapezoidal unless given; ``--refine-up-to N`` limits it to the sizes up to N).
"""

from __future__ import annotations

import argparse
import json
import os
import pstats
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))
import peer_mesh  # noqa: E402
import peer_problem as P  # noqa: E402

AKANTU_VENV = ROOT / ".venv-akantu"
AKANTU_SPEC = "akantu==5.0.7.post1"
ROCKFRAC_PY = ROOT / ".venv" / "bin" / "python"
# rockfrac's threaded runtimes (MKL PARDISO, Numba prange) held to one thread, as Akantu runs
ONE_THREAD = {"MKL_NUM_THREADS": "1", "NUMBA_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}
CODES = ("akantu", "rockfrac", "rockfrac_1t", "rockfrac_be", "rockfrac_refined")


def akantu_python() -> Path:
    """The Akantu virtualenv's Python, created and filled on first use."""
    py = AKANTU_VENV / "bin" / "python"
    if not py.exists():
        subprocess.run([sys.executable, "-m", "venv", str(AKANTU_VENV)], check=True)
        subprocess.run([str(py), "-m", "pip", "install", "--quiet", AKANTU_SPEC], check=True)
    return py


def run_code(python: Path, script: str, mesh: Path, n: int, extra: list[str] = (),
             env: dict | None = None) -> dict:
    """One code on one mesh in a fresh process; its JSON line, plus the load average before."""
    load = os.getloadavg()[0]
    t0 = time.perf_counter()
    proc = subprocess.run([str(python), str(HERE / script), str(mesh), str(n), *extra],
                          stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=mesh.parent,
                          env={**os.environ, **(env or {})})
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        return {"failed": f"exit {proc.returncode}: {proc.stderr.strip()[-400:]}", "N": n,
                "load_before": load}
    r = json.loads(proc.stdout.strip().splitlines()[-1])
    r.update(load_before=load, process_wall_s=wall)
    return r


def accuracy(r: dict, law: str) -> dict:
    """Relative errors [-] of the elastic slope, the peak force, the dissipated energy and the
    whole curve, against the closed forms of the code's own law (peak_problem)."""
    u, f = np.asarray(r["u_top"]), np.asarray(r["force"])
    width = P.WIDTH
    slope = f[0] / u[0] / (width / P.compliance()) - 1.0
    peak = f.max() / (P.SIGMA_C * width) - 1.0
    # work of the top force (trapezoid over the steps) less the elastic energy still stored
    work = float(np.sum(0.5 * (f[1:] + f[:-1]) * np.diff(u)) + 0.5 * f[0] * u[0])
    stored = 0.5 * f[-1] ** 2 * P.compliance() / width
    exact = P.akantu_dissipated if law == "akantu" else P.rockfrac_dissipated
    energy = (work - stored) / (exact(u[-1]) * width) - 1.0
    if law == "akantu":
        curve = np.array([P.akantu_stress(x) for x in u]) * width
        discrete = curve
    else:
        curve = np.array([P.rockfrac_stress(x) for x in u]) * width
        discrete = np.asarray(P.rockfrac_discrete_stresses(list(u), r["work_rule"])) * width
    scale = P.SIGMA_C * width
    return {"slope_err": slope, "peak_err": peak, "energy_err": energy,
            "dissipated": (work - stored) / width, "dissipated_exact": exact(u[-1]),
            "curve_err": float(np.max(np.abs(f - curve)) / scale),
            "discrete_curve_err": float(np.max(np.abs(f - discrete)) / scale)}


def profile_top(path: Path, count: int = 12) -> list[dict]:
    """The functions with the most cumulative time in a cProfile dump."""
    stats = pstats.Stats(str(path))
    rows = []
    for (file, line, name), (_, calls, tottime, cumtime, _) in stats.stats.items():
        rows.append({"function": f"{Path(file).name}:{line}:{name}", "calls": calls,
                     "tottime_s": tottime, "cumtime_s": cumtime})
    return sorted(rows, key=lambda r: -r["tottime_s"])[:count]


def fmt(x: float) -> str:
    return f"{x:.1e}" if x != 0 else "0"


def table(results: list[dict]) -> list[str]:
    """Markdown table: one row per size and code, the ratio on the rockfrac row."""
    lines = ["| N | code | dofs | cohesive elements | steps | Newton its | set-up [s] | loading [s] "
             "| per iteration [ms] | slope err | peak err | energy err | curve err | "
             "ratio rockfrac / akantu (loading) | load avg |", "|---" * 15 + "|"]
    for res in results:
        ak = res["akantu"]
        for r in (res[c] for c in CODES if c in res):
            if "failed" in r:
                lines.append(f"| {res['N']} | {r.get('code', '?')} | failed: {r['failed'][:80]} |"
                             + " |" * 12)
                continue
            a = r["accuracy"]
            curve = fmt(a["curve_err"]) if r is ak else \
                f"{fmt(a['discrete_curve_err'])} ({fmt(a['curve_err'])})"
            ratio = ""
            if r is not ak and "failed" not in ak:
                ratio = f"**{r['loading_s'] / ak['loading_s']:.2f}**"
            lines.append(
                f"| {res['N']} | {r['code']} | {r['dofs']} | {r['cohesive_elements']} | {r['steps']} "
                f"| {r['newton_iterations']} | {r['setup_s']:.2f} | {r['loading_s']:.2f} | "
                f"{1e3 * r['loading_s'] / r['newton_iterations']:.1f} | {fmt(a['slope_err'])} | "
                f"{fmt(a['peak_err'])} | {fmt(a['energy_err'])} | {curve} | {ratio} | "
                f"{r['load_before']:.2f} |")
    return lines


def split_lines(results: list[dict]) -> list[str]:
    """Where rockfrac's loading time goes: assembly and linear solve per Newton iteration."""
    lines = ["| N | rockfrac run | assembly / it [ms] | solve / it [ms] | other / it [ms] | "
             "warm-up (Numba cache, MKL load) [s] | peak memory [GiB] | akantu peak memory [GiB] |",
             "|---" * 8 + "|"]
    for res in results:
        for code in CODES[1:]:
            r = res.get(code, {"failed": "not run"})
            if "failed" in r:
                continue
            its = r["newton_iterations"]
            other = r["loading_s"] - r["assembly_s"] - r["solve_s"]
            lines.append(f"| {res['N']} | {r['code']} | {1e3 * r['assembly_s'] / its:.1f} | "
                         f"{1e3 * r['solve_s'] / its:.1f} | {1e3 * other / its:.1f} | "
                         f"{r['warmup_s']:.1f} | {r['peak_rss_gib']:.2f} | "
                         f"{res['akantu'].get('peak_rss_gib', float('nan')):.2f} |")
    return lines


def write_readme(lines: list[str], head: list[str]) -> None:
    """Replace the table between the peer-table markers of README.md."""
    readme = HERE / "README.md"
    text = readme.read_text()
    start, end = "<!-- peer-table:start -->", "<!-- peer-table:end -->"
    before, rest = text.split(start)
    _, after = rest.split(end)
    readme.write_text(before + start + "\n" + "\n".join(head + [""] + lines) + "\n" + end + after)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[22, 70, 158, 224])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--profile", type=int, default=70, help="cProfile rockfrac at this N")
    ap.add_argument("--refine", type=int, default=1,
                    help="K > 1: an extra rockfrac run with K times the steps")
    ap.add_argument("--refine-rule", default="trapezoidal", choices=["trapezoidal", "backward_euler"],
                    help="work rule of the refined run")
    ap.add_argument("--refine-up-to", type=int, default=224, help="largest N of the refined run")
    args = ap.parse_args()
    sizes = [22] if args.quick else args.sizes
    ak_py = akantu_python()
    results = []
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        for n in sizes:
            mesh = peer_mesh.write_block(Path(tmp) / f"block_{n}.msh", n, P.WIDTH, P.HEIGHT)
            res = {"N": n, "akantu": run_code(ak_py, "peer_akantu.py", mesh, n)}
            extra = []
            if args.profile == n:
                extra = ["--profile", str(Path(tmp) / "rockfrac.prof")]
            res["rockfrac"] = run_code(ROCKFRAC_PY, "peer_rockfrac.py", mesh, n, extra)
            res["rockfrac_1t"] = run_code(ROCKFRAC_PY, "peer_rockfrac.py", mesh, n, env=ONE_THREAD)
            if "failed" not in res["rockfrac_1t"]:
                res["rockfrac_1t"]["code"] = "rockfrac, 1 thread"
            res["rockfrac_be"] = run_code(ROCKFRAC_PY, "peer_rockfrac.py", mesh, n,
                                          ["--work-rule", "backward_euler"])
            if "failed" not in res["rockfrac_be"]:
                res["rockfrac_be"]["code"] = "rockfrac, backward Euler"
            if args.refine > 1 and n <= args.refine_up_to:
                res["rockfrac_refined"] = run_code(ROCKFRAC_PY, "peer_rockfrac.py", mesh, n,
                                                   ["--refine", str(args.refine), "--work-rule",
                                                    args.refine_rule])
                if "failed" not in res["rockfrac_refined"]:
                    rule = args.refine_rule.replace("_", " ")
                    res["rockfrac_refined"]["code"] = f"rockfrac, {rule}, {args.refine}x steps"
            for code in CODES:
                if code in res and "failed" not in res[code]:
                    res[code]["accuracy"] = accuracy(res[code], "akantu" if code == "akantu" else "rockfrac")
            if extra and "failed" not in res["rockfrac"]:
                res["rockfrac"]["profile_top"] = profile_top(Path(extra[1]))
            results.append(res)
            print("\n".join(table([res])[2:]), flush=True)
    total = time.perf_counter() - t0
    head = [f"Problem: {P.WIDTH:g} m x {P.HEIGHT:g} m, E = {P.E:g} Pa, nu = {P.NU}, sigma_c = "
            f"{P.SIGMA_C:g} Pa, G_c = {P.G_C:g} J/m^2, kn = kt = {P.KN:g} Pa/m, {P.STEPS} steps "
            f"of {1e3 * P.step_displacements()[0]:.4f} mm (peak at step {P.STEPS_TO_PEAK}). "
            f"{time.strftime('%Y-%m-%d')}, akantu {results[0]['akantu'].get('version')}; "
            f"rockfrac linear solver: {results[0]['rockfrac'].get('linear_solver')}; akantu: "
            f"{results[0]['akantu'].get('linear_solver')}. Benchmark wall time "
            f"{total / 60:.1f} min."]
    lines = table(results) + [""] + split_lines(results)
    print("\n".join(head + lines))
    if args.quick:
        return
    (HERE / "results").mkdir(exist_ok=True)
    (HERE / "results" / "peer.json").write_text(json.dumps(
        {"problem": {k: getattr(P, k) for k in ("WIDTH", "HEIGHT", "E", "NU", "SIGMA_C", "G_C",
                                                "KN", "KT", "ALPHA_CHI", "STEPS", "STEPS_TO_PEAK",
                                                "TOL_RESIDUAL")},
         "total_wall_s": total, "results": results}, indent=1))
    write_readme(lines, head)


if __name__ == "__main__":
    main()
