"""``rockfrac paper``: the paper's numerical study (Sect. 7, Fig. 5, 7-9) in one command.

Runs the cases, then writes the figures, the CSV behind each figure and report.md into the
output directory. The EDE case joins when the embedded-discontinuity element lands (issue 3).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rockfrac import analytic
from rockfrac.case.schema import parse_case
from rockfrac.output.csvout import read_csv
from rockfrac.run import run_case
from rockfrac.studies import table1


@dataclass
class CaseResult:
    name: str
    history: dict[str, np.ndarray]
    wall: float
    iterations: int
    completed: bool
    message: str


def run_cases(out: Path, axial_steps: int = 400, progress=None) -> list[CaseResult]:
    """Run the paper's cases (path control past the peak) into out/cases/<name>."""
    results = []
    cases = table1.paper_cse_cases(axial_steps=axial_steps, control="path")
    for name, case in cases.items():
        folder = out / "cases" / name.replace(" ", "_").replace("=", "")
        summary = run_case(parse_case(case, name), folder,
                           progress=(lambda row, n=name: progress(n, row)) if progress else None)
        results.append(CaseResult(name, read_csv(folder / "history.csv"), summary.wall_time,
                                  summary.newton_iterations, summary.result.completed, summary.result.message))
    return results


def _write_long_csv(path: Path, results: list[CaseResult], x: str, ys: list[str], transform=None) -> None:
    with open(path, "w") as fh:
        fh.write(",".join(["case", x, *ys]) + "\n")
        for r in results:
            h = r.history
            rows = (h["stage"] == "axial") if x == "u_axial" else (h["n_plastic"] > 0)
            for i in np.flatnonzero(rows):
                vals = [h[y][i] if transform is None else transform(y, h[y][i]) for y in ys]
                fh.write(",".join([r.name, repr(float(h[x][i])), *[repr(float(v)) for v in vals]]) + "\n")


def figures(out: Path, results: list[CaseResult]) -> list[str]:
    """Fig. 5 and Fig. 7-9 as PNG with their CSVs; returns the file names."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    styles = {"EP CSE k=1e9": ("tab:blue", "-"), "EP CSE k=1e8": ("tab:orange", "--"), "RP CSE": ("k", ":")}
    fig, ax = plt.subplots(figsize=(6, 4.2))
    u = np.linspace(0, 6e-4, 50)
    ax.plot(1e3 * u, [analytic.elastic_force(x, table1.CONFINEMENT, 1.5e7, 0.3, 0.04, 0.08) for x in u],
            color="0.7", lw=4, label="uncracked elastic (closed form)")
    for r in results:
        a = r.history["stage"] == "axial"
        c, ls = styles[r.name]
        ax.plot(1e3 * r.history["u_axial"][a], r.history["F_axial"][a], color=c, ls=ls, label=r.name)
    ax.set_xlabel("axial displacement [mm]")
    ax.set_ylabel("axial force [N/m]")
    ax.grid(alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(out / "fig5_force_displacement.png", dpi=150)
    plt.close(fig)
    _write_long_csv(out / "fig5_force_displacement.csv", results, "u_axial", ["F_axial"])
    names = ["fig5_force_displacement.png"]
    specs = [("fig7_cohesion", "c", "cohesion c [Pa]", None),
             ("fig8_friction", "tan_phi", "friction angle phi [rad]", math.atan),
             ("fig9_dilation", "tan_psi", "dilation angle psi [rad]", math.atan)]
    for stem, col, label, fn in specs:
        fig, ax = plt.subplots(figsize=(6, 4.2))
        for r in results:
            pl = r.history["n_plastic"] > 0
            y = r.history[col][pl] if fn is None else np.arctan(r.history[col][pl])
            c, ls = styles[r.name]
            ax.plot(1e3 * r.history["jump_p_norm"][pl], y, color=c, ls=ls, label=r.name)
        ax.set_xlabel("||[u^p]|| [mm]")
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
        ax.legend()
        fig.tight_layout()
        fig.savefig(out / f"{stem}.png", dpi=150)
        plt.close(fig)
        _write_long_csv(out / f"{stem}.csv", results, "jump_p_norm", [col],
                        None if fn is None else (lambda y, v: math.atan(v)))
        names.append(f"{stem}.png")
    return names


def report(out: Path, results: list[CaseResult], names: list[str], wall: float) -> None:
    """report.md: Table 1 as used, the figures, key numbers per case."""
    mc = analytic.mohr_coulomb_force(table1.CONFINEMENT, table1.CRACK_ANGLE, table1.CSE_LAW["c_p"],
                                     math.tan(table1.CSE_LAW["phi_p"]), 0.04)
    lines = [
        "# The paper's numerical study (Regueiro & Yu 2010, Sect. 7), reproduced by rockfrac", "",
        f"Total wall time: {wall:.1f} s. Crack angle {math.degrees(table1.CRACK_ANGLE):.1f} deg (placeholder until the "
        "EDE bifurcation analysis provides it); specimen 40 mm x 80 mm, E = 1.5e7 Pa, nu = 0.3, 20 kPa confinement. "
        "The EDE case is not part of this study yet.", "",
        "## Table 1 (CSE columns) as used", "", "| symbol | value |", "|---|---|",
        *[f"| {k} | {v:g} |" for k, v in table1.CSE_LAW.items()],
        "| kn = kt (EP) | 1e9, 1e8 Pa/m (alpha_chi = alpha_c = 2e3, 2e2) |", "",
        "## Key numbers", "",
        f"Closed-form Mohr-Coulomb activation force on the crack plane: {mc:.1f} N/m.", "",
        "| case | peak force [N/m] | final force [N/m] | final u [mm] | Newton iterations | wall [s] | completed |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in results:
        h = r.history
        lines.append(f"| {r.name} | {np.nanmax(h['F_axial']):.1f} | {h['F_axial'][-1]:.1f} | "
                     f"{1e3 * h['u_axial'][-1]:.3f} | {r.iterations} | {r.wall:.2f} | {'yes' if r.completed else 'no: ' + r.message} |")
    lines += ["", "## Figures", ""] + [f"![{n}]({n})" for n in names]
    (out / "report.md").write_text("\n".join(lines) + "\n")


def run_paper(out: str | Path, axial_steps: int = 400, progress=None) -> list[CaseResult]:
    """The whole study into ``out``; returns the per-case results."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    results = run_cases(out, axial_steps, progress)
    names = figures(out, results)
    report(out, results, names, time.perf_counter() - t0)
    return results
