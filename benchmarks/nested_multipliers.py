"""RP surfaces with their multipliers among the unknowns (the saddle point) against nested ones.

One command (``python benchmarks/nested_multipliers.py [--cases ...]``). ``[cohesive] multipliers`` =
"unknowns" and "nested" on the same cases, one after the other (the ratios are what to read):
- *paper*: the paper's RP case (tests/conftest.py's, 100 steps to 3 mm, through activation and
  softening), run ``--repeats`` times each, the fastest kept (the first run of a process compiles);
- *every*: the 4 x 6 quad specimen with RP surfaces on every internal edge (loops of 4 pairs
  round each interior node), confined and compressed elastically (tests/test_real_meshes.py);
- *grains*: the grain-matrix specimen of ``fragmentation.py --specimen grains`` cut to 4 grains
  in 12 x 24 mm, quads of 0.9 mm, RP on every internal edge (r = 2e12 Pa/m, the EP's kn), the viscous
  regularisation of ``fragmentation.py`` (eta r the same), load control, 50 nominal steps to 0.4 mm,
  until it ends (about 10 minutes);
- *joints*: ``scaling_3d.py --problem joints-rp`` at 127,413 dofs (32^3 hexahedra), PARDISO (about 4
  minutes).
The rows of the cases not run again are kept (each with its own date and load average).
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


def joints_3d(folder: Path) -> dict:
    """benchmarks/scaling_3d.py's RP joints at 127,413 dofs: a box of 32^3 hexahedra in 4 slabs with RP
    joints between them, under a top pressure on rollers (elastic: the unsplit box), PARDISO."""
    from scaling_3d import JOINT_LAW, LAYERS, NU, P, E

    from rockfrac.mesh import rock_tests as rt

    msh = rt.box(folder / "box.msh", (1.0, 1.0, 1.0), (32, 32, 32), element="hex8", layers=LAYERS)
    return {"title": "box", "mesh": {"kind": "gmsh", "file": str(msh)}, "bulk": {"E": E, "nu": NU},
            "stages": [{"name": "press", "displacement": {"left": {"x": 0.0}, "front": {"y": 0.0}, "bottom": {"z": 0.0}},
                        "pressure": {"top": P}}],
            "cohesive": {"where": "boundaries", "form": "rp", **JOINT_LAW}, "solver": {"linear": "pardiso"},
            "output": {"vtk": False, "picture": False, "points": False}}


CASES = {  # name: (label, the case's maker (given a scratch folder), the load reported, repeats or None: --repeats)
    "paper": ("paper's RP case, 100 steps to 3 mm", lambda folder: paper(), "F_axial", None),
    "every": ("4 x 6 quads, RP on every edge, elastic", lambda folder: every_edge(), "F_axial", None),
    "grains": ("small grains, RP on every edge, 50 steps to 0.4 mm", small_grains, "R_top_y", 1),
    "joints": ("3D joints, 32^3 hex8 in 4 slabs, PARDISO", joints_3d, "R_bottom_z", 1),
}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", nargs="*", choices=sorted(CASES), default=sorted(CASES),
                    help="the cases to run (the saved rows of the others are kept; none: publish the table again)")
    ap.add_argument("--repeats", type=int, default=3, help="runs of the paper's and the every-edge case, each way")
    args = ap.parse_args()
    saved = HERE / "results" / "nested_multipliers.json"
    record = {"machine": machine(), "load_start": os.getloadavg(), "results": []}
    if saved.exists():  # the rows of the cases not run again (each with its own date and load)
        old = json.loads(saved.read_text())
        labels = {CASES[name][0] for name in args.cases}
        record["results"] = [r for r in old["results"] if r["case"] not in labels]
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.cases:
            label, make, load, repeats = CASES[name]
            for how in HOW:
                runs = [run_one(make(Path(tmp)), how, Path(tmp) / f"{how}_{k}", load)
                        for k in range(repeats or args.repeats)]
                best = min(runs, key=lambda r: r["wall_s"])
                best.update(case=label, multipliers=how, date=machine()["date"], load_average=os.getloadavg()[0])
                print(best, flush=True)
                record["results"].append(best)
    order = [c[0] for c in CASES.values()]
    record["results"].sort(key=lambda r: (order.index(r["case"]), HOW.index(r["multipliers"])))
    m = record["machine"]
    publish("nested_multipliers", record, table(record),
            f"{m['cpu']}, {m['cores']} cores; each row's date and load average (at its end) are its own run's.")


def table(record: dict) -> list[str]:
    """The lines of the table of a record's results."""
    rows = []
    for r in record["results"]:
        base = next(s for s in record["results"] if s["case"] == r["case"] and s["multipliers"] == "unknowns")
        when = f"{r['date']}, {r['load_average']:.2f}" if "date" in r else f"{record['machine']['date']}, -"
        rows.append([r["case"], r["multipliers"], r["dofs"], r["steps"], r["iterations"], r["updates"],
                     f"{r['wall_s']:.2f}", f"{r['wall_s'] / base['wall_s']:.2f}", f"{r['peak']:.6g}", r["ended"], when])
    return markdown_table(["case", "multipliers", "unknowns", "steps", "Newton iterations (converged steps)",
                           "multiplier updates (failed steps too)", "wall [s]", "wall / the saddle point's",
                           "peak load [N/m; 3D: N]", "ended", "date, load average"], rows)


if __name__ == "__main__":
    main()
