"""Probe (issue 15): cohesive points per edge instead of per node pair, on the small grains specimen.

With cohesive surfaces on every edge, each node is split into one copy per cell, and rockfrac's nodal
points (one per node pair, paper Sect. 6.2) tie the copies round a node in a ring. Rigid-plastic
(RP) pairs on a ring must have flows that sum to zero, so a crack that bends at a node, or meets
unyielded pairs there, cannot slide: the small grains stop at 0.17-0.36 of their stage where EP runs
whole (benchmarks/README.md, "Smoothed normals"). This probe compares, on the small grains:

- ``nodal``: rockfrac's points (``[cohesive] points = "nodes"``: two constraints per node pair, four
  per edge);
- ``mean``: one point per edge on the edge's mean jump, two constraints an edge, so no ring, and no
  moment on the edge's relative rotation (a hinge; ``points = "edges"`` with the moment switched off);
- ``mean+rotation``: ``[cohesive] points = "edges"`` as it is (rockfrac.elements.cse_facets): the mean
  jump and the moment k L (g - g_p)^2 / 24 on the difference g of the edge's end normal jumps, its end
  tractions capped at the point's tensile strength (since 2026-12-02, sitting 61);
- ``mean+elastic-rotation``: the same with the moment elastic whatever the point's state (the edge
  points until sitting 61).

``--specimen rocking``: a block rocking and sliding on one horizontal surface instead (the paper's
specimen, 40 x 80 mm, with its crack turned horizontal at mid-height, on ``--edges`` n edges: n x 2n
quads; the paper's law and bulk), pressed by 20 kPa on its top, then pushed sideways at its top, which
may rise and tilt: the heel of the surface opens in tension while its toe is pressed, the case an
edge's bending is for. R_top_x against the push, for each n.

Measured results: benchmarks/README.md, "Points per edge" and "A block rocking on one surface".
``.venv/bin/python benchmarks/edge_points.py [--points nodal mean mean+rotation] [--forms ep rp]``
(each run 40-200 s on one thread).
"""

from __future__ import annotations

import argparse
import csv
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import rockfrac.case.build_groups as build_groups
from rockfrac.case.schema import parse_case
from rockfrac.runner import run_case
from rockfrac.studies import table1

sys.path.insert(0, str(Path(__file__).resolve().parent))
from fragmentation import grains_case  # noqa: E402

FRACTIONS = (0.15, 0.3, 0.5, 0.75, 1.0)
EDGE_GROUPS = build_groups.facet_groups


def hinged_edge_groups(*args, **kwargs) -> list:
    """points = 'edges' without the moment on the edges' rotation."""
    groups = EDGE_GROUPS(*args, **kwargs)
    for g in groups:
        g.rotation_stiffness = 0.0
    return groups


def elastic_moment_edge_groups(*args, **kwargs) -> list:
    """points = 'edges' with the moment on the edges' rotation elastic (no cap)."""
    groups = EDGE_GROUPS(*args, **kwargs)
    for g in groups:
        g.moment_cap = False
    return groups


POINTS = {"nodal": "nodes", "corners": "corners"}  # [cohesive] points of each kind (the rest: edge points)
VARIANTS = {"mean": hinged_edge_groups, "mean+elastic-rotation": elastic_moment_edge_groups}


def small_grains(form: str, points: str, steps: int, displacement: float, k: float, eta: float, runs: Path,
                 size: float = 0.002) -> dict:
    """The small grains specimen of benchmarks/README.md (12 x 24 mm, 4 grains, quads of ``size``, 2 mm
    by default, with 24 nodes on each grain's circle at 2 mm and more in proportion on a finer mesh; the
    grains' places do not depend on it), viscous, load control; EP's kn = kt = RP's augmentation = k."""
    d = grains_case(size, runs)
    d["mesh"].update(width=0.012, height=0.024, n_grains=4, points_per_circle=max(24, round(24 * 0.002 / size)))
    d["output"] = {"vtk": False, "picture": False, "points": False}
    st = d["stages"][0]
    st.update(steps=steps, control="load")
    st.pop("max_steps")
    st["displacement"]["top"]["y"] = -displacement
    st["stop"]["below_peak_fraction"] = 0.05
    for c in d["cohesive"]:
        c.update(form=form, viscosity=eta, points=points)
        if form == "rp":
            c.pop("kn")
            c.pop("kt")
            c["augmentation"] = k
        else:
            c["kn"] = c["kt"] = k
    return d


def rocking_block(form: str, points: str, steps: int, displacement: float, k: float, n: int) -> dict:
    """The paper's specimen (40 x 80 mm, n x 2n quads) with its crack horizontal at mid-height and the
    paper's law on it (EP: kn = kt = k; RP: augmentation k), held at its base, pressed by 20 kPa on its
    top (2 steps), then its top pushed sideways by ``displacement`` in ``steps`` (free to rise and tilt)."""
    coh = dict(table1.CSE_LAW, form=form, points=points)
    coh.update({"kn": k, "kt": k} if form == "ep" else {"augmentation": k})
    return {
        "title": "a block rocking on one surface",
        "mesh": {"kind": "specimen", "width": 0.04, "height": 0.08, "crack": True, "crack_angle": 0.0,
                 "nx": n, "ny": 2 * n},
        "bulk": dict(table1.BULK),
        "cohesive": coh,
        "stages": [
            {"name": "press", "steps": 2, "displacement": {"bottom": {"x": 0.0, "y": 0.0}, "top": {"x": 0.0}},
             "pressure": {"top": table1.CONFINEMENT}},
            {"name": "push", "steps": steps, "displacement": {"top": {"x": displacement}}},
        ],
        "output": {"vtk": False, "picture": False, "points": False},
    }


def each_run(tmp: str, sizes: list, args: argparse.Namespace, make):
    """Run make(form, points, size) for each size, kind of points and form in turn: yields (size, kind,
    form, summary, wall [s], the history's rows of the last stage, their load factors, how it ended)."""
    for size, kind in ((h, kind) for h in sizes for kind in args.points):
        build_groups.facet_groups = VARIANTS.get(kind, EDGE_GROUPS)
        for form in args.forms:
            out = Path(tmp) / f"{kind}_{form}_{size:g}"
            t0 = time.perf_counter()
            s = run_case(parse_case(make(form, POINTS.get(kind, "edges"), size), "<edge_points>"), out)
            wall = time.perf_counter() - t0
            rows = list(csv.DictReader(open(out / "history.csv")))
            rows = [r for r in rows if r["stage"] == rows[-1]["stage"]]
            lam = np.array([float(r["load_factor"]) for r in rows])
            ended = "stage done" if s.result.completed else f"stopped at {lam[-1]:.3f}"
            yield size, kind, form, s, wall, rows, lam, ended


def at_fractions(lam: np.ndarray, values: np.ndarray, fmt: str) -> list[str]:
    """values at the load factors nearest FRACTIONS (within 0.02, else '-')."""
    idx = [int(np.argmin(np.abs(lam - f))) for f in FRACTIONS]
    return [format(values[i], fmt) if abs(lam[i] - f) < 0.02 else "-" for i, f in zip(idx, FRACTIONS)]


def rocking(args: argparse.Namespace) -> None:
    """The rocking block's table: peak and R_top_x at fractions of the push, for each n, points and form."""
    print("| edges | points | form | steps | wall [s] | ended | peak [N/m] | "
          + " | ".join(f"R_top_x at {f}" for f in FRACTIONS) + " | D [J/m] |")
    print("|---" * (8 + len(FRACTIONS)) + "|")
    with tempfile.TemporaryDirectory() as tmp:
        def make(form: str, points: str, n: int) -> dict:
            return rocking_block(form, points, args.steps, args.displacement, args.k, n)

        for n, kind, form, s, wall, rows, lam, ended in each_run(tmp, args.edges, args, make):
            force = np.array([float(r["R_top_x"]) for r in rows])
            print(f"| {n} | {kind} | {form.upper()} | {s.result.steps} | {wall:.0f} | {ended} | {force.max():.1f} | "
                  + " | ".join(at_fractions(lam, force, ".1f")) + f" | {float(rows[-1]['D_dissipated']):.4f} |",
                  flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", nargs="+", default=["nodal", "mean", "mean+rotation"],
                    choices=["nodal", "mean", "mean+rotation", "mean+elastic-rotation", "corners"])
    ap.add_argument("--forms", nargs="+", default=["ep", "rp"], choices=["ep", "rp"])
    ap.add_argument("--steps", type=int, default=50)
    ap.add_argument("--displacement", type=float, default=4e-4, help="the top's shortening [m]")
    ap.add_argument("--k", type=float, default=2e12, help="EP's kn = kt, RP's augmentation, the moment's k [Pa/m]")
    ap.add_argument("--viscosity", type=float, default=2.5e-5)
    ap.add_argument("--size", type=float, nargs="+", default=[0.002],
                    help="element sizes [m] (several: a refinement study, each size's runs in turn)")
    ap.add_argument("--specimen", choices=["grains", "rocking"], default="grains")
    ap.add_argument("--edges", type=int, nargs="+", default=[4, 8, 16, 32],
                    help="rocking: the surface's edges n (n x 2n quads)")
    args = ap.parse_args()
    if args.specimen == "rocking":
        rocking(args)
        return
    print("| size [mm] | points | form | interface points | steps | wall [s] | ended | "
          + " | ".join(f"R_top_y at {f}" for f in FRACTIONS) + " | D [J/m] |")
    print("|---" * (8 + len(FRACTIONS)) + "|")
    with tempfile.TemporaryDirectory() as tmp:
        def make(form: str, points: str, size: float) -> dict:
            return small_grains(form, points, args.steps, args.displacement, args.k, args.viscosity, Path(tmp), size)

        for size, kind, form, s, wall, rows, lam, ended in each_run(tmp, args.size, args, make):
            load = np.array([-float(r["R_top_y"]) for r in rows])
            points = sum(g.points.n for g in s.built.cohesives)
            print(f"| {1e3 * size:g} | {kind} | {form.upper()} | {points} | {s.result.steps} | {wall:.0f} | {ended} | "
                  + " | ".join(at_fractions(lam, load, ".0f")) + f" | {float(rows[-1]['D_dissipated']):.4f} |",
                  flush=True)


if __name__ == "__main__":
    main()
