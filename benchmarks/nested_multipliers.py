"""RP surfaces with their multipliers among the unknowns (the saddle point) against nested ones.

One command (``python benchmarks/nested_multipliers.py``). ``[cohesive] multipliers`` = "unknowns"
and "nested" on the same cases, in the same invocation (the ratios are what to read):
- *paper*: the paper's RP case (tests/conftest.py's, 100 steps to 3 mm, through activation and
  softening), run ``--repeats`` times each, the fastest kept (the first run of a process compiles);
- *every edge*: the 4 x 6 quad specimen with RP surfaces on every internal edge (loops of 4 pairs
  round each interior node), confined and compressed elastically (tests/test_real_meshes.py);
- *small grains*: the grain-matrix specimen of ``fragmentation.py --specimen grains`` cut to 4 grains
  in 12 x 24 mm, quads of 0.9 mm, RP on every internal edge (r = 2e12 Pa/m, the EP's kn), the viscous
  regularisation of ``fragmentation.py`` (eta r the same), load control, 50 nominal steps to 0.4 mm,
  until it ends (``--grains 0`` leaves it out: it takes about 15 minutes).
Reported per run: steps, Newton iterations (an update of nested multipliers counts as one, a
solve-free one), the multiplier updates, wall time, where it ended, the peak load. Results go to
results/nested_multipliers.json and the "Nested multipliers" table of benchmarks/README.md.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent / "tests"))
from fragmentation import grains_case  # noqa: E402
from run import machine, markdown_table, publish  # noqa: E402

HOW = ("unknowns", "nested")


def paper() -> dict:
    from conftest import paper_case

    return paper_case("rp", axial_displacement=3e-3, axial_steps=100)


def every_edge() -> dict:
    from conftest import EVERY_EDGE

    from rockfrac.studies import table1

    return dict(EVERY_EDGE, cohesive=dict(table1.CSE_LAW, form="rp", where="all"))


def small_grains(folder: Path) -> dict:
    d = grains_case(0.0009, folder)
    d["mesh"].update(width=0.012, height=0.024, n_grains=4)
    stage = d["stages"][0]
    stage.update(steps=50, control="load")
    stage.pop("max_steps")
    stage["displacement"]["top"]["y"] = -4e-4
    for c in d["cohesive"]:
        c.update(form="rp", augmentation=c.pop("kn"), viscosity=2.5e-5)
        c.pop("kt")
    d["output"] = {"vtk": False, "picture": False, "points": False}
    return d


def run_one(case: dict, how: str, out: Path, load: str) -> dict:
    from rockfrac.case.schema import parse_case
    from rockfrac.output.csvout import read_csv
    from rockfrac.runner import run_case

    sections = case["cohesive"] if isinstance(case["cohesive"], list) else [case["cohesive"]]
    for c in sections:
        c["multipliers"] = how
    t0 = time.perf_counter()
    s = run_case(parse_case(case), out, overwrite=True)
    wall = time.perf_counter() - t0
    h = read_csv(out / "history.csv")
    log = (out / "run.log").read_text()
    lam = re.search(r"at load factor ([0-9.]+)", s.result.message)
    return {"steps": int(s.result.steps), "iterations": int(h["newton_iterations"].sum()),
            "updates": log.count("multipliers updated"), "wall_s": wall, "completed": bool(s.result.completed),
            "ended": "completed" if s.result.completed else f"min_step at load factor {lam.group(1)}" if lam
            else s.result.message[:80], "peak": float(abs(h[load]).max()), "dofs": int(s.built.model.n_dofs)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3, help="runs of the paper's and the every-edge case, each way")
    ap.add_argument("--grains", type=int, default=1, help="1: the small grains too (about 15 minutes); 0: not")
    ap.add_argument("--table", action="store_true", help="publish the saved results' table again, running nothing")
    args = ap.parse_args()
    if args.table:
        record = json.loads((HERE / "results" / "nested_multipliers.json").read_text())
        m, load = record["machine"], (record["load_start"][0], record["load_end"][0])
        footer = f"{m['cpu']}, {m['cores']} cores; load average {load[0]:.2f} at the start, {load[1]:.2f} at the end."
        end = record["load_end"]
        publish("nested_multipliers", record, table(record), footer)
        record["load_end"] = end  # the run's, not this republication's
        (HERE / "results" / "nested_multipliers.json").write_text(json.dumps(record, indent=1))
        return
    record = {"machine": machine(), "load_start": os.getloadavg(), "results": []}
    cases = [("paper's RP case, 100 steps to 3 mm", paper, "F_axial", args.repeats),
             ("4 x 6 quads, RP on every edge, elastic", every_edge, "F_axial", args.repeats)]
    if args.grains:
        cases.append(("small grains, RP on every edge, 50 steps to 0.4 mm", None, "R_top_y", 1))
    with tempfile.TemporaryDirectory() as tmp:
        for label, make, load, repeats in cases:
            for how in HOW:
                runs = [run_one(make() if make else small_grains(Path(tmp)), how, Path(tmp) / f"{how}_{k}", load)
                        for k in range(repeats)]
                best = min(runs, key=lambda r: r["wall_s"])
                best.update(case=label, multipliers=how)
                print(best, flush=True)
                record["results"].append(best)
    publish("nested_multipliers", record, table(record))


def table(record: dict) -> list[str]:
    """The lines of the table of a record's results."""
    rows = []
    for r in record["results"]:
        base = next(s for s in record["results"] if s["case"] == r["case"] and s["multipliers"] == "unknowns")
        rows.append([r["case"], r["multipliers"], r["dofs"], r["steps"], r["iterations"], r["updates"],
                     f"{r['wall_s']:.2f}", f"{r['wall_s'] / base['wall_s']:.2f}", f"{r['peak']:.6g}", r["ended"]])
    return markdown_table(["case", "multipliers", "unknowns", "steps", "Newton iterations (converged steps)",
                           "multiplier updates (failed steps too)", "wall [s]", "wall / the saddle point's",
                           "peak load [N/m]", "ended"], rows)


if __name__ == "__main__":
    main()
