"""Step growth on the grains example's specimen: RP against EP surfaces on the grain boundaries.

One command: ``.venv/bin/python benchmarks/step_growth.py`` (about 4 minutes on 2 cores). Runs
examples/grains/grains.toml (40 grains in a perfectly plastic matrix, surfaces on every grain/matrix
boundary, 1.4 mm of unconfined compression in 44 nominal steps) four ways: RP surfaces with both
platens held in x (rough platens), EP surfaces (the example's kn = kt = 1e11 Pa/m) with rough
platens, RP with rough platens and ``[solver] easy_iterations = 16``, and RP surfaces as the example
is (one corner held in x). For each: steps, Newton
iterations (those of failed steps included, from run.log), failed steps, how far it got, the force
there and the wall time. Writes ``results/step_growth.json`` and the ``step-growth-table`` of
README.md ("Step growth").
"""

from __future__ import annotations

import os
import sys
import time
import tomllib
from pathlib import Path

import numpy as np

HERE = Path(__file__).parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))
from run import machine, markdown_table, publish  # noqa: E402

AXIAL = 1.4e-3  # the example's platen displacement [m]


def case(form: str, rough: bool, easy: int | None = None) -> dict:
    """The grains example with ``form`` surfaces, its platens rough (both held in x) or as given, and
    ``[solver] easy_iterations`` (None: the default)."""
    d = tomllib.loads((ROOT / "examples" / "grains" / "grains.toml").read_text())
    if easy is not None:
        d["solver"] = {"easy_iterations": easy}
    coh = d["cohesive"]
    coh["form"] = form
    if form == "rp":  # no penalty: the augmentation's default
        coh.pop("kn")
        coh.pop("kt")
    if rough:
        steps = d["loading"]["axial_steps"]
        d.pop("loading")
        d["stages"] = [{"name": "axial", "steps": steps,
                        "displacement": {"bottom": {"x": 0.0, "y": 0.0}, "top": {"x": 0.0, "y": -AXIAL}}}]
    d["output"] = {"vtk": False, "picture": False, "points": False}
    return d


def main() -> None:
    from rockfrac.case.schema import parse_case
    from rockfrac.output.csvout import read_csv
    from rockfrac.runner import run_case

    runs = {"RP, rough platens": ("rp", True, None), "EP, rough platens": ("ep", True, None),
            "RP, rough platens, easy_iterations = 16": ("rp", True, 16),
            "RP, one corner held in x (the example)": ("rp", False, None)}
    record: dict = {"machine": machine(), "load_start": os.getloadavg(), "runs": {}}
    rows = []
    for name, (form, rough, easy) in runs.items():
        tag = f"{form}_{'rough' if rough else 'example'}" + (f"_easy{easy}" if easy else "")
        out = HERE / "results" / "runs" / f"step_growth_{tag}"  # gitignored
        t0 = time.perf_counter()
        s = run_case(parse_case(case(form, rough, easy)), out, overwrite=True)
        wall = time.perf_counter() - t0
        h = read_csv(out / "history.csv")
        log = (out / "run.log").read_text()
        iterations = sum(1 for line in log.splitlines() if " it " in line and ": residual" in line
                         and " it 0:" not in line)
        force = float(np.abs(h["R_top_y"][-1]))
        rec = {"steps": int(s.result.steps), "iterations": iterations, "failed": log.count("cutting back"),
               "reached_mm": 1e3 * AXIAL * float(h["load_factor"][-1]), "completed": bool(s.result.completed),
               "force_N_per_m": force, "wall_s": wall, "ended": s.result.message[:200]}
        record["runs"][name] = rec
        rows.append([name, rec["steps"], rec["iterations"], rec["failed"],
                     f"{rec['reached_mm']:.3f}" + (" (completed)" if rec["completed"] else " (stops)"),
                     f"{force:.0f}", f"{wall:.0f}"])
        print(name, rec, flush=True)
    lines = markdown_table(["run", "steps", "Newton iterations (failed steps included)", "failed steps",
                            "reached [mm]", "F [N/m]", "wall [s]"], rows)
    publish("step_growth", record, lines)


if __name__ == "__main__":
    main()
