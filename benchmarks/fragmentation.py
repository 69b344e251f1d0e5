"""Fragmentation: a Brazilian disc with cohesive surfaces on every internal edge, EP against RP, two
step sizes, run until the load falls below half its peak.

One command: ``.venv/bin/python benchmarks/fragmentation.py [--size 0.0009]`` (about 15 minutes on 2
cores). The disc of examples/rock_tests/brazilian (50 mm, loaded over two 10 deg arcs) meshed at
``--size`` (0.9 mm: about 5,100 internal edges), the bilinear law of everywhere.toml on every internal
edge, path control on the mean opening, at 100 and 200 nominal steps. EP (penalty 1e15 Pa/m) runs
with ``[solver] fallback = "implex"`` (IMPL-EX once an implicit step fails at min_step), and again
under load control with the viscous regularisation ``[cohesive] viscosity`` instead (the energy a
snap-back releases goes to D_viscous, reported); RP has no such fallback (its multipliers have no
elastic jump to extrapolate). Reports per run: internal edges
(interface points), steps, Newton iterations per step, the step where IMPL-EX took over, wall time,
peak load, the dissipated energy (the work of the forces, and the law's own account) and how the run
ended. Writes ``results/fragmentation.json`` and the ``fragmentation-table`` of README.md.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import sys
import time
import tomllib
from pathlib import Path

import numpy as np

HERE = Path(__file__).parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))
from run import machine, markdown_table, publish  # noqa: E402

VISCOSITY = 1e-6  # [cohesive] viscosity of the load-controlled EP runs (pseudo-time; the stage = 1)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--size", type=float, default=0.0009)
    args = ap.parse_args()
    from rockfrac.case.schema import parse_case
    from rockfrac.mesh.rock_tests import disc
    from rockfrac.output.csvout import read_csv
    from rockfrac.runner import run_case

    runs = HERE / "results" / "runs"
    runs.mkdir(parents=True, exist_ok=True)
    msh = disc(runs / f"disc_{args.size:g}.msh", diameter=0.05, contact_angle=math.radians(10.0),
               element_size=args.size)
    base = tomllib.loads((ROOT / "examples" / "rock_tests" / "brazilian" / "everywhere.toml").read_text())
    base["mesh"]["file"] = str(msh)
    base["output"] = {"vtk": False, "picture": False, "points": False}
    record: dict = {"machine": machine(), "load_start": os.getloadavg(), "size": args.size, "runs": {}}
    rows = []
    for variant in ("ep", "ep viscous", "rp"):
        form = variant.split()[0]
        for steps in (100, 200):
            d = json.loads(json.dumps(base))
            coh = d["cohesive"]
            coh["form"] = form
            stage = d["stages"][0]
            stage["steps"] = steps
            stage["max_steps"] = 40 * steps
            if form == "rp":
                coh.pop("kn")
                coh.pop("kt")
            elif variant == "ep viscous":  # load control; the overstress ~ eta kn dJ/dt stays ~1 % of sigma_c
                coh["viscosity"] = VISCOSITY
                stage["control"] = "load"
                stage.pop("max_steps")
            else:
                d["solver"] = {"fallback": "implex"}
            out = runs / f"fragment_{variant.replace(' ', '_')}_{steps}"
            t0 = time.perf_counter()
            s = run_case(parse_case(d), out, overwrite=True)
            wall = time.perf_counter() - t0
            h = read_csv(out / "history.csv")
            log = (out / "run.log").read_text()
            r = np.abs(h["R_load_top_y"])
            its = h["newton_iterations"]
            switched = None
            if "switch to IMPL-EX" in log:
                switched = int(h["step"][np.flatnonzero(np.diff(its == 1))[-1] + 1])
            points = sum(g.points.n for g in s.built.cohesives)
            lam = re.search(r"at load factor ([0-9.]+)", s.result.message)
            ended = ("below half the peak" if "fell below" in s.result.message else
                     f"no convergence at min_step, load factor {lam.group(1)}" if lam else s.result.message[:60])
            viscous = float(h["D_viscous"][-1]) if "D_viscous" in h else 0.0
            rec = {"points": points, "steps": int(s.result.steps), "iterations": int(its.sum()),
                   "iterations_per_step": float(its.mean()), "implex_from_step": switched, "wall_s": wall,
                   "peak_N_per_m": float(r.max()), "end_fraction": float(r[-1] / r.max()),
                   "D_dissipated": float(h["D_dissipated"][-1]), "D_surface_law": float(h["D_surface_law"][-1]),
                   "D_viscous": viscous, "energy_error": float(h["energy_error"][-1]), "ended": ended}
            record["runs"][f"{variant} {steps}"] = rec
            print(variant, steps, rec, flush=True)
            rows.append([variant.upper() if variant != "ep viscous" else f"EP, viscosity {VISCOSITY:g}, load control",
                         steps, points, rec["steps"], f"{rec['iterations_per_step']:.2f}",
                         switched if switched is not None else "-", f"{wall:.0f}", f"{r.max() / 1e3:.0f}",
                         f"{rec['end_fraction']:.2f}", f"{rec['D_dissipated']:.4f}", f"{rec['D_surface_law']:.4f}",
                         f"{viscous:.4f}", ended])
    lines = markdown_table(["form", "nominal steps", "interface points", "steps", "Newton it./step",
                            "IMPL-EX from step", "wall [s]", "peak [kN/m]", "end / peak", "D (work) [J/m]",
                            "D (law) [J/m]", "D (viscous) [J/m]", "ended"], rows)
    publish("fragmentation", record, lines)

if __name__ == "__main__":
    main()
