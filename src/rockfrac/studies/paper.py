"""``rockfrac paper``: the paper's numerical study (Sect. 7, Table 1, Fig. 5-9) in one command.

Runs the EDE and the three CSE cases (and, beyond the paper, the EP CSE with k = 1e8 and the
unreduced softening rates the paper could not converge), then writes the figures, the CSV behind
each figure and report.md, whose claims are computed from the runs.
"""

from __future__ import annotations

import csv
import math
import os
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from rockfrac import analytic
from rockfrac.case.schema import parse_case
from rockfrac.files import prepare_output
from rockfrac.output.csvout import read_csv
from rockfrac.runner import RunSummary, run_case
from rockfrac.studies import table1

EDE, EP9, EP8, RP = "EDE", "EP CSE k=1e9", "EP CSE k=1e8", "RP CSE"
BEYOND = "EP CSE k=1e8, alpha=2e3"
PAPER_CASES = (EDE, EP9, EP8, RP)
STYLES = {EDE: ("tab:green", "-"), EP9: ("tab:blue", "-"), EP8: ("tab:orange", "--"), RP: ("k", ":"),
          BEYOND: ("tab:red", "-.")}
W, H = 0.04, 0.08
RESIDUAL = table1.CONFINEMENT * W  # closed-form residual force of c_r = phi_r = 0 [N/m]


@dataclass
class CaseResult:
    name: str
    history: dict[str, np.ndarray]
    points: dict[str, np.ndarray]
    summary: RunSummary  # its model (``built``) dropped where the case ran in a worker process
    deformed: tuple[float, dict[str, list[np.ndarray]]]  # Fig. 6: magnification and polylines

    @property
    def completed(self) -> bool:
        return self.summary.result.completed

    @property
    def message(self) -> str:
        return self.summary.result.message

    @property
    def iterations(self) -> int:
        return self.summary.newton_iterations

    @property
    def wall(self) -> float:
        return self.summary.wall_time


def study_cases(axial_steps: int = 400) -> dict[str, dict]:
    """Case dictionaries of the study: the EDE (same step size, three times as far), the CSEs."""
    cases = {EDE: table1.ede_case(axial_steps=3 * axial_steps)}
    cases.update(table1.paper_cse_cases(axial_steps=axial_steps, control="path"))
    cases[BEYOND] = table1.cse_case("ep", 1e8, 2e3, axial_steps=axial_steps, control="path",
                                    title="EP CSE, kn = kt = 1e8 Pa/m, alpha_chi = alpha_c = 2e3 (beyond the paper)")
    return cases


def _folder(out: Path, name: str) -> Path:
    return out / "cases" / name.replace(" ", "_").replace("=", "").replace(",", "")


PROGRESS_KEYS = ("step", "newton_iterations", "u_axial", "F_axial")  # what a worker reports per step


def deformed(summary: RunSummary) -> tuple[float, dict[str, list[np.ndarray]]]:
    """The final deformed mesh of a run for Fig. 6: (magnification, polylines)."""
    from rockfrac.output.plots import deformed_polylines, magnification

    mag = magnification(summary.built, summary.result.u)
    return mag, deformed_polylines(summary.built, summary.result.u, mag)


def _worker(conn, cases: dict[str, dict], out: str, with_progress: bool) -> None:
    """A worker process: runs the cases the parent sends by name until it sends None, reporting each
    step (when asked) and each case's summary without its model (whose load paths hold closures) but
    with what the figures need of it; a failure is sent back as its traceback."""
    import traceback

    while (name := conn.recv()) is not None:
        try:
            progress = None
            if with_progress:
                def progress(row: dict, n: str = name) -> None:
                    conn.send(("row", n, {k: row[k] for k in PROGRESS_KEYS}))
            summary = run_case(parse_case(cases[name], name), _folder(Path(out), name), overwrite=True,
                               progress=progress)
            shape = deformed(summary)
            summary.built = None
            conn.send(("done", name, (summary, shape)))
        except BaseException:  # noqa: BLE001 - any failure goes back to the parent, which raises it
            conn.send(("error", name, traceback.format_exc()))
            return


def run_cases(out: Path, axial_steps: int = 400, progress=None, jobs: int = 1, on_result=None
              ) -> tuple[list[CaseResult], str]:
    """Run the study's cases into out/cases/<name>, ``jobs`` at a time in worker processes (1: one
    after the other in this process), handing each result to ``on_result`` as its case ends;
    returns the results in the study's order and where they ran. Each case is deterministic
    (rockfrac.solve.linear fixes MKL's threading layer), so the results are the same bits either
    way (tested)."""
    cases = study_cases(axial_steps)
    results: dict[str, CaseResult] = {}

    def finished(name: str, summary: RunSummary, shape: tuple) -> None:
        folder = _folder(out, name)
        results[name] = CaseResult(name, read_csv(folder / "history.csv"), read_csv(folder / "points.csv"),
                                   summary, shape)
        if on_result is not None:
            on_result(results[name])

    where = "in one process"
    if jobs > 1:
        method = _run_parallel(out, cases, progress, jobs, finished)
        where = f"on {min(jobs, len(cases))} worker processes ({method})"
    else:
        for name, case in cases.items():
            step_progress = None
            if progress is not None:
                def step_progress(row: dict, n: str = name) -> None:
                    progress(n, row)
            summary = run_case(parse_case(case, name), _folder(out, name), overwrite=True, progress=step_progress)
            finished(name, summary, deformed(summary))
    return [results[name] for name in cases], where


# the order the workers take the cases: the longest first, then those of Fig. 5-9 (their figures
# are then drawn while the last case, beyond the paper, still runs)
DISPATCH = (EDE, RP, EP9, EP8, BEYOND)


def fork_is_safe() -> bool:
    """Whether this process may fork its workers: Linux, no other Python thread (e.g. a progress
    display's refresher), Numba's thread pool not started and no OpenMP runtime loaded (MKL's
    PARDISO brings one; a pool forked half-way hangs the child). NumPy's and SciPy's OpenBLAS pools
    are stopped across a fork by their own handlers. A forked worker starts at once, every module
    imported; a spawned one imports rockfrac again (about a second)."""
    import multiprocessing
    import sys
    import threading

    if not sys.platform.startswith("linux") or "fork" not in multiprocessing.get_all_start_methods():
        return False
    if threading.active_count() != 1:
        return False
    parallel = sys.modules.get("numba.np.ufunc.parallel")
    if parallel is not None and getattr(parallel, "_is_initialized", True):
        return False
    try:
        with open("/proc/self/maps", encoding="utf-8") as maps:
            return not any(lib in line for line in maps for lib in ("libgomp", "libiomp", "libomp"))
    except OSError:
        return False


def _run_parallel(out: Path, cases: dict[str, dict], progress, jobs: int, finished) -> str:
    """The cases on ``jobs`` worker processes (forked where that is safe, else spawned) in the order
    of DISPATCH, each worker given the next case when it is done; step rows come back as they
    are made, each case's summary goes to ``finished`` as it ends. Returns the start method.
    Matplotlib is imported before the workers start, so no one imports it twice."""
    import multiprocessing
    from multiprocessing.connection import wait

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot  # noqa: F401 - for the crack maps and the figures

    method = "fork" if fork_is_safe() else "spawn"
    context: Any = multiprocessing.get_context(method)  # typeshed's BaseContext lacks Process
    queue = sorted(cases, key=lambda n: DISPATCH.index(n) if n in DISPATCH else len(DISPATCH))
    workers = []
    for _ in range(min(jobs, len(queue))):
        parent, child = context.Pipe()
        proc = context.Process(target=_worker, args=(child, cases, str(out), progress is not None), daemon=True)
        proc.start()
        child.close()
        parent.send(queue.pop(0))
        workers.append((proc, parent))
    try:
        running = {conn: proc for proc, conn in workers}  # the workers with a case
        while running:
            ready = wait(list(running) + [proc.sentinel for proc in running.values()])
            for conn, proc in list(running.items()):
                while conn in running and conn.poll():
                    try:
                        kind, name, payload = conn.recv()
                    except EOFError:
                        break
                    if kind == "row":
                        progress(name, payload)
                    elif kind == "error":
                        raise RuntimeError(f"case {name!r} failed in a worker process:\n{payload}")
                    else:
                        if queue:
                            conn.send(queue.pop(0))
                        else:
                            conn.send(None)  # the worker ends
                            running.pop(conn)
                        finished(name, *payload)
                if conn in running and proc.sentinel in ready and not conn.poll():
                    raise RuntimeError(f"a worker process of rockfrac paper died (exit code {proc.exitcode}) "
                                       "before reporting its case")
        return method
    finally:
        for proc, conn in workers:
            proc.join(timeout=5.0 if not running else 0.0)
            if proc.is_alive():
                proc.terminate()
                proc.join()
            conn.close()


# --- numbers ------------------------------------------------------------------------------------


def _first(mask: np.ndarray) -> int | None:
    idx = np.flatnonzero(mask)
    return int(idx[0]) if idx.size else None


def key_numbers(r: CaseResult) -> dict:
    """Yield and bifurcation force, angle, c_p, peak and residual force of a case."""
    h, p = r.history, r.points
    ax = h["stage"] == "axial"
    out = {"peak": float(np.nanmax(h["F_axial"][ax])), "final": float(h["F_axial"][-1]),
           "final_u": float(h["u_axial"][-1]), "iterations": r.iterations, "wall": r.wall}
    plastic = h["bulk_plastic"] > 0 if r.name == EDE else h["n_plastic"] > 0
    k = _first(plastic & ax)
    out["yield"] = float(h["F_axial"][k - 1]) if k else math.nan  # last elastic / rigid step
    if r.name == EDE:
        onset = _first(h["n_localized"] > 0)
        out["bifurcation"] = float(h["F_axial"][onset]) if onset is not None else math.nan
        out["u_bifurcation"] = float(h["u_axial"][onset]) if onset is not None else math.nan
        out["angle"] = float(p["angle"][0]) if p["angle"].size else math.nan
        out["c_p"] = float(p["c_p"][0]) if p["c_p"].size else math.nan
    else:
        out["bifurcation"] = math.nan
        out["angle"] = float(np.mean(p["angle"]))
        out["c_p"] = table1.CSE_LAW["c_p"]
    return out


def _pre_peak_slope(h: dict) -> float:
    """Secant dF/du of the axial stage up to 80% of the peak (elastic or rigid part)."""
    ax = (h["stage"] == "axial") & (h["n_plastic"] == 0)
    u, f = h["u_axial"][ax], h["F_axial"][ax]
    keep = f <= 0.8 * np.nanmax(h["F_axial"])
    if np.unique(u[keep]).size < 2:  # steps too coarse to leave two elastic points below 80 % of the peak
        return math.nan
    return float(np.polyfit(u[keep], f[keep], 1)[0])


def claims(results: dict[str, CaseResult]) -> list[tuple[str, str]]:
    """The paper's qualitative claims, each with the number that supports it."""
    out = []
    rp = results[RP].history
    pre = (rp["n_plastic"] == 0)
    elastic = np.array([analytic.elastic_force(u, table1.CONFINEMENT * (lf if s == "confinement" else 1.0),
                                               table1.BULK["E"], table1.BULK["nu"], W, H)
                        for u, s, lf in zip(rp["u_axial"], rp["stage"], rp["load_factor"])])
    dev = np.max(np.abs(rp["F_axial"][pre] - elastic[pre]) / np.abs(elastic[pre]))
    out.append(("RP CSE follows the uncracked elastic curve until activation",
                f"max relative deviation {dev:.1e} over {int(pre.sum())} steps before activation"))
    s_rp, s9, s8 = (_pre_peak_slope(results[k].history) for k in (RP, EP9, EP8))
    p_rp, p9 = (key_numbers(results[k])["peak"] for k in (RP, EP9))
    def pct(ratio: float) -> str:
        return (f"{100 * (ratio - 1):+.1f} %" if math.isfinite(ratio)
                else "not measurable at this step count (fewer than two elastic steps below 80 % of the peak)")

    series = analytic.series_slope(1.5e7, 0.3, W, H, 1e8, 1e8, table1.CRACK_ANGLE)
    out.append(("EP CSE k = 1e9 is nearly the RP curve",
                f"pre-peak slope {pct(s9 / s_rp)}, peak force {100 * (p9 / p_rp - 1):+.2f} % vs RP"))
    out.append(("EP CSE k = 1e8 is visibly softer before the peak",
                f"pre-peak slope {pct(s8 / s_rp)} vs RP (series compliance: {pct(series / s_rp)})"))
    e = key_numbers(results[EDE])
    out.append(("EDE: the force rises after Drucker-Prager yield (plane strain)",
                f"first yield at {e['yield']:.0f} N/m, peak {e['peak']:.0f} N/m (+{100 * (e['peak'] / e['yield'] - 1):.1f} %)"))
    out.append(("EDE: bifurcation (det A = 0) near 3700 N/m",
                f"{e['bifurcation']:.0f} N/m at u = {1e3 * e['u_bifurcation']:.3f} mm, band at "
                f"{math.degrees(e['angle']):.3f} deg from horizontal, c_p (eq. 28) = {e['c_p']:.0f} Pa (paper: 9053 Pa)"))
    out.append(("EDE: exponential softening to a residual",
                f"final force {e['final']:.1f} N/m vs the closed-form residual p W = {RESIDUAL:.0f} N/m "
                f"({100 * (e['final'] / RESIDUAL - 1):+.2f} %)"))
    h_rp, h_ep = results[RP].history, results[EP9].history
    grid = np.linspace(0.05, 0.9, 30) * min(np.nanmax(h_rp["jump_p_norm"]), np.nanmax(h_ep["jump_p_norm"]))
    worst = 0.0
    for col, scale in (("c", table1.CSE_LAW["c_p"]), ("tan_phi", math.tan(table1.CSE_LAW["phi_p"])),
                       ("tan_psi", math.tan(table1.CSE_LAW["psi_p"]))):
        a = np.interp(grid, _mono(h_rp["jump_p_norm"]), h_rp[col][np.isfinite(h_rp["jump_p_norm"])])
        b = np.interp(grid, _mono(h_ep["jump_p_norm"]), h_ep[col][np.isfinite(h_ep["jump_p_norm"])])
        worst = max(worst, float(np.max(np.abs(a - b)) / scale))
    out.append(("EP (1e9) and RP CSE have the same ISV histories versus ||[u^p]||",
                f"max difference of c, tan phi, tan psi {100 * worst:.2f} % of their peaks"))
    b = results[BEYOND]
    back = np.any(np.diff(b.history["u_axial"][b.history["control"] == "path"]) < 0)
    out.append(("Beyond the paper: EP CSE k = 1e8 with the unreduced rates (alpha = 2e3) runs to completion",
                f"{'completed' if b.completed else 'stopped: ' + b.message}; "
                f"{'snap-back traced by path following' if back else 'no snap-back'}, "
                f"{len(b.history['step'])} steps, peak {key_numbers(b)['peak']:.0f} N/m"))
    return out


def _mono(x: np.ndarray) -> np.ndarray:
    x = x[np.isfinite(x)]
    return np.maximum.accumulate(x)


# --- figures --------------------------------------------------------------------------------------


def _long_csv(path: Path, header: list[str], rows) -> None:
    """A CSV in long form (quoted where needed: case names hold commas)."""
    with open(path, "w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow(header)
        w.writerows([v if isinstance(v, str) else repr(float(v)) for v in row] for row in rows)


def _force_figure(out: Path, stem: str, results: list[CaseResult], title: str | None = None) -> None:
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    u = np.linspace(0.0, 6e-4, 50)
    ax.plot(1e3 * u, [analytic.elastic_force(x, table1.CONFINEMENT, 1.5e7, 0.3, W, H) for x in u],
            color="0.75", lw=4, label="uncracked elastic (closed form)")
    rows = []
    for r in results:
        a = r.history["stage"] == "axial"
        c, ls = STYLES[r.name]
        ax.plot(1e3 * r.history["u_axial"][a], r.history["F_axial"][a], color=c, ls=ls, label=r.name)
        rows += [(r.name, uu, ff) for uu, ff in zip(r.history["u_axial"][a], r.history["F_axial"][a])]
    ax.axhline(RESIDUAL, color="0.5", lw=0.8, ls=":")
    ax.set_xlabel("axial displacement [mm]")
    ax.set_ylabel("axial force [N/m]")
    if title:
        ax.set_title(title, fontsize=9)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out / f"{stem}.png", dpi=150)
    plt.close(fig)
    _long_csv(out / f"{stem}.csv", ["case", "u_axial", "F_axial"], rows)


ISV_FIGURES = {"fig7_cohesion": ("c", "cohesion c [Pa]"), "fig8_friction": ("tan_phi", "friction angle phi [rad]"),
               "fig9_dilation": ("tan_psi", "dilation angle psi [rad]")}


def _isv_figure(out: Path, stem: str, results: list[CaseResult]) -> None:
    """Fig. 7-9: an internal variable of the surfaces against ||[u^p]||."""
    import matplotlib.pyplot as plt

    col, label = ISV_FIGURES[stem]
    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    rows = []
    for r in results:
        pl = r.history["n_plastic"] > 0
        x = r.history["jump_p_norm"][pl]
        y = r.history[col][pl] if col == "c" else np.arctan(r.history[col][pl])
        c, ls = STYLES[r.name]
        ax.plot(1e3 * x, y, color=c, ls=ls, label=r.name)
        rows += [(r.name, xx, yy) for xx, yy in zip(x, y)]
    ax.set_xlabel("||[u^p]|| [mm]")
    ax.set_ylabel(label)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out / f"{stem}.png", dpi=150)
    plt.close(fig)
    _long_csv(out / f"{stem}.csv", ["case", "jump_p_norm", "c" if col == "c" else col.replace("tan_", "")], rows)


def _mesh_figure(out: Path, results: dict[str, CaseResult]) -> tuple[str, dict[str, float]]:
    """Fig. 6: deformed (solid) and undeformed (dashed) meshes of the EDE and the EP CSE."""
    import matplotlib.pyplot as plt

    from rockfrac.output.plots import draw_deformed

    fig, axes = plt.subplots(1, 2, figsize=(7.2, 5.6))
    rows, mags = [], {}
    for ax, name in zip(axes, (EDE, EP9)):
        mag, lines = results[name].deformed
        mags[name] = mag
        what = "one Hex8, embedded crack" if name == EDE else "two Q4, cohesive surface"
        draw_deformed(ax, lines, f"{name} ({what})\nu = {1e3 * results[name].history['u_axial'][-1]:.2f} mm, "
                                 f"displacements x {mag:g}")
        for kind, polys in lines.items():
            for i, poly in enumerate(polys):
                rows += [(name, kind, str(i), x, y) for x, y in poly]
    fig.tight_layout()
    fig.savefig(out / "fig6_deformed_meshes.png", dpi=150)
    plt.close(fig)
    _long_csv(out / "fig6_deformed_meshes.csv", ["case", "line", "index", "x", "y"], rows)
    return "fig6_deformed_meshes.png", mags


FIGURES = (("fig5_force_displacement", PAPER_CASES), ("fig6_deformed_meshes", (EDE, EP9)),
           ("fig7_cohesion", PAPER_CASES), ("fig8_friction", PAPER_CASES), ("fig9_dilation", PAPER_CASES),
           ("fig5b_unreduced_rates", (EP8, BEYOND, RP)))  # Fig. 5-9 and, beyond the paper, Fig. 5b; their cases


class Figures:
    """Fig. 5-9 (and Fig. 5b) as PNG with their CSVs, each drawn as soon as the cases it shows are in,
    so the figures of finished cases are drawn while the last ones still run."""

    def __init__(self, out: Path):
        import matplotlib

        matplotlib.use("Agg")
        self.out = out
        self.by: dict[str, CaseResult] = {}
        self.mags: dict[str, float] = {}  # Fig. 6's displacement magnification of each case drawn
        self.drawn: set[str] = set()

    def add(self, result: CaseResult) -> None:
        """Take a finished case and draw every figure whose cases are now all in."""
        self.by[result.name] = result
        for stem, needs in FIGURES:
            if stem not in self.drawn and all(n in self.by for n in needs):
                self._draw(stem, [self.by[n] for n in needs])
                self.drawn.add(stem)

    def _draw(self, stem: str, results: list[CaseResult]) -> None:
        if stem == "fig5_force_displacement":
            _force_figure(self.out, stem, results)
        elif stem == "fig5b_unreduced_rates":
            _force_figure(self.out, stem, results, "Beyond the paper: EP CSE k = 1e8 with alpha = 2e3 (path following)")
        elif stem == "fig6_deformed_meshes":
            self.mags = _mesh_figure(self.out, self.by)[1]
        else:
            _isv_figure(self.out, stem, results)

    def names(self) -> list[str]:
        """The figures' files in the report's order (every one drawn, else a RuntimeError)."""
        missing = [stem for stem, _ in FIGURES if stem not in self.drawn]
        if missing:
            raise RuntimeError(f"figures not drawn, their cases missing: {missing}")
        return [f"{stem}.png" for stem, _ in FIGURES]


# --- report ---------------------------------------------------------------------------------------


def report(out: Path, results: list[CaseResult], names: list[str], mags: dict[str, float], wall: float,
           where: str = "in one process") -> None:
    """report.md: Table 1 as used, the key numbers per case, the claims with numbers, the figures."""
    by = {r.name: r for r in results}
    mc = analytic.mohr_coulomb_force(table1.CONFINEMENT, table1.CRACK_ANGLE, table1.CSE_LAW["c_p"],
                                     math.tan(table1.CSE_LAW["phi_p"]), W)
    dp = table1.DRUCKER_PRAGER
    lines = [
        "# The paper's numerical study (Regueiro & Yu 2010, Sect. 7), reproduced by rockfrac", "",
        f"Total wall time {wall:.1f} s, the cases {where}. Specimen 40 mm x 80 mm, plane strain, E = 1.5e7 Pa, nu = 0.3, "
        f"20 kPa confinement then top shortening. CSEs through the centre at {math.degrees(table1.CRACK_ANGLE):.4f} deg "
        "from horizontal: the band angle where det A = 0 for the EDE's bulk (computed, see below).", "",
        "## Table 1 as used", "",
        "| symbol | EDE | EP CSE | RP CSE |", "|---|---|---|---|",
        "| kt = kn | - | 1e9, 1e8 Pa/m | - |",
        f"| GfI = GfII | - | {table1.CSE_LAW['GfI']:g} J/m^2 | {table1.CSE_LAW['GfI']:g} J/m^2 |",
        f"| chi_p, chi_r | - | {table1.CSE_LAW['chi_p']:g}, 0 Pa | {table1.CSE_LAW['chi_p']:g}, 0 Pa |",
        f"| c_p | eq. (28): {key_numbers(by[EDE])['c_p']:.0f} Pa | {table1.CSE_LAW['c_p']:g} Pa | {table1.CSE_LAW['c_p']:g} Pa |",
        "| c_r | 0 | 0 | 0 |",
        f"| phi_p, phi_r | {table1.EDE_LAW['phi_p']}, 0 rad | {table1.CSE_LAW['phi_p']}, 0 rad | {table1.CSE_LAW['phi_p']}, 0 rad |",
        f"| psi_p | {table1.EDE_LAW['psi_p']} rad | {table1.CSE_LAW['psi_p']} rad | {table1.CSE_LAW['psi_p']} rad |",
        "| alpha_chi | - | 2e3, 2e2 | 2e3 |", "| alpha_c | 5e2 1/m | 2e3, 2e2 | 2e3 |",
        "| alpha_phi, alpha_psi | 5e2 1/m | 9e2 | 9e2 |", "",
        f"EDE bulk, Drucker-Prager (the paper's ref [9], recovered from the author's Tahoe input; see "
        f"scripts/calibrate_dp.py): kappa0 = {dp['kappa0']:g} Pa, beta = {dp['beta']}, b = {dp['b']}, "
        f"H = {dp['H']:.6g} Pa (Tahoe's -1e6 Pa in F = ... - H gamma).", "",
        "## Key numbers", "",
        f"Closed-form Mohr-Coulomb activation force of the CSE plane: {mc:.1f} N/m; closed-form residual "
        f"(c_r = phi_r = 0): confinement x width = {RESIDUAL:.0f} N/m.", "",
        "| case | yield [N/m] | bifurcation [N/m] | angle [deg] | c_p [Pa] | peak [N/m] | final [N/m] at u [mm] | Newton its | wall [s] | completed |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in results:
        k = key_numbers(r)
        bif = "-" if math.isnan(k["bifurcation"]) else f"{k['bifurcation']:.1f}"
        lines.append(f"| {r.name} | {k['yield']:.1f} | {bif} | {math.degrees(k['angle']):.3f} | {k['c_p']:.0f} | "
                     f"{k['peak']:.1f} | {k['final']:.1f} at {1e3 * k['final_u']:.2f} | {k['iterations']} | "
                     f"{k['wall']:.2f} | {'yes' if r.completed else 'no: ' + r.message} |")
    lines += ["", "Yield: the last step before anything yields (EDE: the Drucker-Prager bulk; CSE: the surface). "
              "Bifurcation: the step where det A / det A^e reaches 0 (located within the step).", "",
              "## The paper's claims, checked", ""]
    lines += [f"- **{claim}**: {number}." for claim, number in claims(by)]
    lines += ["", "## Figures", ""]
    captions = {"fig6_deformed_meshes.png": "Fig. 6: deformed (solid) and undeformed (dashed) meshes, displacements x "
                + ", ".join(f"{mags[k]:g} ({k})" for k in mags) + ". The EDE's crack, invisible in the paper, is drawn inside its element: its - face red, its + face blue "
                "(dashed); the upper block has slid down and to the left along it."}
    for n in names:
        lines += [f"![{n}]({n})", "", captions.get(n, ""), ""]
    (out / "report.md").write_text("\n".join(lines) + "\n")


def run_paper(out: str | Path, axial_steps: int = 400, progress=None, jobs: int = 1) -> list[CaseResult]:
    """The whole study into ``out`` (``jobs`` cases at a time); returns the per-case results."""
    out = prepare_output(out, ())  # a folder we can write; the study rewrites its own outputs
    t0 = time.perf_counter()
    figures = Figures(out)
    results, where = run_cases(out, axial_steps, progress, jobs, figures.add)
    report(out, results, figures.names(), figures.mags, time.perf_counter() - t0, where)
    return results
