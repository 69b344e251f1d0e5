"""PARDISO with and without its weighted matching, and in the saddle order, on RP saddle points with surfaces
on every edge.

One command (``python benchmarks/saddle_pardiso.py``). Two sets of real tangents, each with its
Newton right-hand side, kept from runs whose linear solves are SuperLU's (accurate):
- *grains*: the grain-matrix specimen with RP surfaces on every edge, one point per edge
  (``fragmentation.py --specimen grains --variants "rp viscous" --steps 100 --points edges``), resumed
  from its checkpoint at step 328 (0.979 of its 1 mm, past the peak, with plastic points;
  results/saddle_pardiso_grains_edges_step328.tar.xz, the run's bundle then): its next ``--grains``
  systems (62,792 rows);
- *disc*: the coarse Brazilian disc with RP surfaces on every edge (examples/rock_tests/brazilian/
  everywhere.toml made RP, as tests/test_rock_tests.py runs it): its first ``--disc`` systems (3,664 rows).
Each backend then solves each set in order, as the Newton loop does: analysed and factorized at
each load step's first system, refactorized on that analysis for the step's others (PARDISO's
matching is computed at the analysis; without the matching the analysis reads the pattern only and,
since 2026-12-03, is kept from step to step, so its "analysis" column times a refactorization after
the first step), one solve each. Reported: the median refactorization and solve, the relative residual
|A x - b| / |b| of the solves (median, largest), how many are above 1e-6 (the accuracy
``rockfrac.solve.fallback.Checked`` asks for) and how many remain above it after the checked
solve's refinement with the backend's own factors. Results go to results/saddle_pardiso.json and
the "PARDISO without matching" table of benchmarks/README.md.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tarfile
import tempfile
import time
import tomllib
from pathlib import Path

import numpy as np

HERE = Path(__file__).parent
# the grains' RP run's checkpoint at step 328 (its bundle, kept here: the run itself has ended)
GRAINS_AT_328 = HERE / "results" / "saddle_pardiso_grains_edges_step328.tar.xz"
sys.path.insert(0, str(HERE))
from fragmentation import BUNDLED, base_case, variant_case  # noqa: E402
from run import machine, markdown_table, publish  # noqa: E402


class Kept(BaseException):
    """Enough systems are kept: ends the run that makes them (not an error of the run)."""


def recorder(systems: list, count: int):
    """SuperLU, keeping each factorized matrix, the first right-hand side solved with it and whether it
    is its load step's first."""
    from rockfrac.solve.linear import SuperLU

    step = {"new": True}

    class Recorder(SuperLU):
        name = "superlu (recording)"

        def begin_step(self) -> None:
            step["new"] = True

        def _factorize(self, a):
            factor = super()._factorize(a)
            matrix = a.copy()

            class Keep:
                def solve(self, b):
                    systems.append((matrix, np.array(b, copy=True), step["new"]))
                    step["new"] = False
                    if len(systems) >= count:
                        raise Kept
                    return factor.solve(b)

            return Keep()

    return Recorder()


def grains_systems(count: int, folder: Path) -> tuple[list, int]:
    """The next ``count`` systems of the grains' RP run from its checkpoint at step 328, and the
    number of displacement dofs (the multipliers follow)."""
    import rockfrac.runner as runner
    from rockfrac.case.schema import parse_case

    args = argparse.Namespace(specimen="grains", displacement=None, stop_fraction=0.5, augmentation=None,
                              penalty=None, elimination=False, checkpoint_every=10, normals="pairs",
                              points="edges")
    base, visc = base_case(args, 0.004, folder)
    d, name, _ = variant_case(base, args, "rp viscous", 100, visc)
    out = folder / name
    out.mkdir(parents=True)
    with tarfile.open(GRAINS_AT_328, "r:xz") as tar:  # plain files only, into the run folder
        tar.extractall(out, members=[m for m in tar.getmembers() if m.isfile() and m.name in BUNDLED],
                       filter="data")
    systems: list = []
    nodes: list = []
    make = runner.make_solver

    def recording(name, coordinates, *rest, **options):  # the run's linear solver, recording
        nodes.append(coordinates)
        return recorder(systems, count)

    runner.make_solver = recording
    # the checkpoint was written with the edges' moment elastic (before 2026-12-02, sitting 61): resumed
    # as such, without the capped bending's state
    from rockfrac.elements.cse_facets import FacetRP
    from rockfrac.elements.cse_groups import CohesiveRP
    kept = FacetRP.checkpoint_attrs
    FacetRP.checkpoint_attrs, FacetRP.moment_cap = CohesiveRP.checkpoint_attrs, False
    try:
        runner.run_case(parse_case(d), out, resume=True)
    except Kept:
        pass
    finally:
        runner.make_solver = make
        FacetRP.checkpoint_attrs = kept
        del FacetRP.moment_cap
    return systems, int(nodes[0].size)


def disc_systems(count: int) -> tuple[list, int]:
    """The first ``count`` systems of the coarse disc with RP surfaces on every edge, and the number
    of displacement dofs (the multipliers follow)."""
    from rockfrac.case.build import build
    from rockfrac.case.schema import parse_case
    from rockfrac.solve.newton import NewtonOptions
    from rockfrac.solve.stepping import SteppingOptions, run_stages

    path = HERE.parent / "examples" / "rock_tests" / "brazilian" / "everywhere.toml"
    d = tomllib.loads(path.read_text())
    d["mesh"]["file"] = str(path.parent / d["mesh"]["file"])
    d["stages"][0]["steps"] = 50
    d["solver"] = {"max_iterations": 12}
    coh = d["cohesive"]
    coh["form"], coh["augmentation"] = "rp", coh.pop("kn")
    coh.pop("kt")
    d.setdefault("output", {})["vtk"] = False
    built = build(parse_case(d, str(path)))
    systems: list = []
    try:
        run_stages(built.model, built.stages, recorder(systems, count), NewtonOptions(), SteppingOptions(),
                   lambda info: None)
    except Kept:
        pass
    return systems, int(built.mesh.nodes.size)


def measure(backend, systems: list) -> dict:
    """``backend`` on ``systems`` in order: analysed at each load step's first, refactorized for the
    step's others (medians of each); one solve each."""
    from rockfrac.solve.fallback import ACCURACY, _refined, relative_residual

    analysed, refactor, solve, raw, after = [], [], [], [], []
    for k, (a, b, new_step) in enumerate(systems):
        if new_step:
            backend.begin_step()  # matched PARDISO analyses afresh (its matching from this matrix), as in a run
        t0 = time.perf_counter()
        factor = backend.factorize(a)
        t1 = time.perf_counter()
        x = factor.solve(b)
        t2 = time.perf_counter()
        (analysed if new_step or k == 0 else refactor).append(t1 - t0)
        solve.append(t2 - t1)
        res = relative_residual(a, x, b)
        raw.append(res)
        after.append(_refined(factor, a, b, x, res, ACCURACY)[1] if res > ACCURACY else res)
    return {"backend": backend.name, "systems": len(systems), "rows": int(systems[0][0].shape[0]),
            "steps": len(analysed), "analysed_s": statistics.median(analysed),
            "refactor_s": statistics.median(refactor) if refactor else None, "solve_s": statistics.median(solve),
            "residual_median": float(np.median(raw)), "residual_max": float(np.max(raw)),
            "above": int(np.sum(np.array(raw) > ACCURACY)), "above_after_refinement": int(np.sum(np.array(after) > ACCURACY))}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--grains", type=int, default=12, help="systems of the grains' RP run (0: none)")
    ap.add_argument("--disc", type=int, default=200, help="systems of the coarse disc's RP run (0: none)")
    args = ap.parse_args()
    from rockfrac.solve.linear import Pardiso, SuperLU

    record: dict = {"machine": machine(), "load_start": os.getloadavg(), "results": []}
    sets = []
    with tempfile.TemporaryDirectory() as tmp:
        if args.grains:
            sets.append(("grains, RP on every edge (edge points), from step 328", *grains_systems(args.grains, Path(tmp))))
        if args.disc:
            sets.append(("coarse disc, RP on every edge", *disc_systems(args.disc)))
    for label, systems, n_u in sets:
        for backend in (Pardiso(), Pardiso(matching=False), Pardiso(matching=False, multipliers_from=n_u), SuperLU()):
            row = measure(backend, systems)
            row["set"] = label
            print(row, flush=True)
            record["results"].append(row)
    rows = []
    for r in record["results"]:
        base = next(s for s in record["results"] if s["set"] == r["set"] and s["backend"] == "superlu")
        rows.append([r["set"], r["backend"], r["rows"], r["systems"], r["steps"], f"{r['analysed_s']:.2f}", f"{r['refactor_s']:.2f}",
                     f"{r['solve_s']:.3f}", f"{(r['refactor_s'] + r['solve_s']) / (base['refactor_s'] + base['solve_s']):.2f}",
                     f"{r['residual_median']:.1e}", f"{r['residual_max']:.1e}", r["above"], r["above_after_refinement"]])
    lines = markdown_table(["tangents", "backend", "rows", "systems", "load steps", "analysis + factorization [s]", "refactorization [s]",
                            "solve [s]", "refactor + solve / SuperLU's", "residual (median)", "residual (largest)",
                            "above 1e-6", "after refinement"], rows)
    publish("saddle_pardiso", record, lines)


if __name__ == "__main__":
    main()
