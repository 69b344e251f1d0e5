"""Probe (issue 15): cohesive points per edge instead of per node pair, on the small grains specimen.

With cohesive surfaces on every edge, each node is split into one copy per cell, and rockfrac's nodal
points (one per node pair, paper Sect. 6.2) tie the copies round a node in a ring. Rigid-plastic
(RP) pairs on a ring must have flows that sum to zero, so a crack that bends at a node, or meets
unyielded pairs there, cannot slide: the small grains stop at 0.17-0.36 of their stage where EP runs
whole (benchmarks/README.md, "Smoothed normals"). This probe swaps the points of every cohesive set
for one point per interface cell (edge) before the run, and compares:

- ``nodal``: rockfrac's points (two constraints per node pair: four per edge);
- ``mean``: one point at the edge's midpoint whose jump is the edge's mean jump,
  [[u]] = ((u_p0 - u_m0) + (u_p1 - u_m1)) / 2, weight the edge's length: two constraints an edge, so
  no ring, but each edge's relative rotation is free (a hinge);
- ``mean+rotation``: ``mean`` with an elastic moment on that rotation: the energy
  k L g^2 / 24, g = n . ((u_p1 - u_m1) - (u_p0 - u_m0)) the difference of the end normal jumps, k the
  EP's penalty kn, L the edge (kn times the square of a linear normal jump's zero-mean part,
  integrated along the edge). No unknown is added.

The points' law, RP return, viscosity and multipliers are rockfrac's own: the probe maps each point's
element vector and block of its (minus, plus[, multiplier]) rows onto the edge's four nodes (a half
to each end). It is a probe, not a feature: serial, 2D, load control, no points.csv. It monkeypatches
``rockfrac.case.build.cohesive_groups``. Measured results: benchmarks/README.md, "Points per edge".

``.venv/bin/python benchmarks/edge_points.py [--points nodal mean mean+rotation] [--forms ep rp]``
(each run 40-200 s on one thread).
"""

from __future__ import annotations

import argparse
import csv
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

import rockfrac.case.build as build_module
from rockfrac.case.build_groups import cohesive_groups as nodal_groups, law_of_section
from rockfrac.case.cohesive_section import CohesiveForm
from rockfrac.case.schema import parse_case
from rockfrac.elements.cse_groups import CohesiveEP, CohesiveRP
from rockfrac.elements.interface_points import InterfacePoints
from rockfrac.runner import run_case

sys.path.insert(0, str(Path(__file__).resolve().parent))
from fragmentation import grains_case  # noqa: E402

FRACTIONS = (0.15, 0.3, 0.5, 0.75, 1.0)


def edge_points(nodes: np.ndarray, cells: np.ndarray) -> tuple[InterfacePoints, np.ndarray, np.ndarray]:
    """One point per interface cell (m0, m1, p0, p1) at its midpoint, weight its length [m], frame (t, n)
    as rockfrac's; the points' minus/plus are the cells' first pair, (m1, p1) returned beside."""
    xm0, xm1 = nodes[cells[:, 0]], nodes[cells[:, 1]]
    length = np.linalg.norm(xm1 - xm0, axis=1)
    t = (xm1 - xm0) / length[:, None]
    frame = np.stack([t, np.stack([-t[:, 1], t[:, 0]], axis=1)], axis=1)
    k = np.arange(cells.shape[0])
    pts = InterfacePoints(minus=cells[:, 0].copy(), plus=cells[:, 2].copy(), weight=length, frame=frame,
                          x=0.5 * (xm0 + xm1), cell=k, segments=np.asarray(cells, dtype=np.int64),
                          segment_points=np.stack([k, k], axis=1), segment_x=np.stack([xm0, xm1], axis=1))
    return pts, cells[:, 1].copy(), cells[:, 3].copy()


class _EdgeMean:
    """Mixin: the jump of a point is its edge's mean jump; element rows mapped onto the edge's nodes."""

    rotation_stiffness = 0.0  # k [Pa/m] of the moment on the edge's relative rotation (0: a hinge)

    def _edge_setup(self, m1: np.ndarray, p1: np.ndarray, multipliers: bool) -> None:
        d = self.dim
        ar = np.arange(d)
        jd = self.points.dofs
        self.jump_dofs = np.concatenate([jd[:, :d], d * m1[:, None] + ar, jd[:, d:], d * p1[:, None] + ar], axis=1)
        self.dofs = self.jump_dofs
        rows = (3 if multipliers else 2) * d
        e = np.zeros((rows, rows + 2 * d))
        for i in range(d):
            e[i, i] = e[i, d + i] = 0.5  # minus rows: half to m0, half to m1
            e[d + i, 2 * d + i] = e[d + i, 3 * d + i] = 0.5  # plus rows: p0, p1
            if multipliers:
                e[2 * d + i, 4 * d + i] = 1.0
        self._expand = e
        n = self.points.frame[:, 1]
        self._rotation = np.concatenate([n, -n, -n, n], axis=1)  # g = c . u over (m0, m1, p0, p1)

    def jumps(self, u: np.ndarray) -> np.ndarray:
        d, j = self.dim, self.jump_dofs
        return 0.5 * (u[j[:, 2 * d:3 * d]] - u[j[:, :d]] + u[j[:, 3 * d:4 * d]] - u[j[:, d:2 * d]])

    def _on_edges(self, ev, u: np.ndarray):
        e = self._expand
        fe, ke = ev.fe @ e, np.einsum("ai,nab,bj->nij", e, ev.ke, e)
        if self.rotation_stiffness > 0.0:
            c, n4 = self._rotation, self._rotation.shape[1]
            k = self.rotation_stiffness * self.points.weight / 12.0
            g = np.einsum("pi,pi->p", c, u[self.jump_dofs])
            fe[:, :n4] += (k * g)[:, None] * c
            ke[:, :n4, :n4] += k[:, None, None] * np.einsum("pi,pj->pij", c, c)
        return replace(ev, fe=fe, ke=ke)


class EdgeEP(_EdgeMean, CohesiveEP):
    def __init__(self, points, m1, p1, law, name, viscosity, rotation_stiffness):
        CohesiveEP.__init__(self, points, law, name=name, viscosity=viscosity)
        self.rotation_stiffness = rotation_stiffness
        self._edge_setup(m1, p1, multipliers=False)

    def evaluate(self, u, u_n):
        return self._on_edges(CohesiveEP.evaluate(self, u, u_n), u)


class EdgeRP(_EdgeMean, CohesiveRP):
    def __init__(self, points, m1, p1, law, aug, name, viscosity, rotation_stiffness):
        CohesiveRP.__init__(self, points, law, aug, junction=np.zeros(points.n, dtype=bool), name=name,
                            viscosity=viscosity)
        self.rotation_stiffness = rotation_stiffness
        self._edge_setup(m1, p1, multipliers=True)

    @property
    def total_points(self) -> int:
        return self.points.n

    @total_points.setter
    def total_points(self, value: int) -> None:  # the build sets its nodal set's count (serial: ignored)
        pass

    def redundant_extras(self, dirichlet):
        d = self.dim
        held = np.isin(self.jump_dofs, dirichlet)
        out = [self.lam_dofs[held[:, a] & held[:, d + a] & held[:, 2 * d + a] & held[:, 3 * d + a], a]
               for a in range(d)]
        return np.concatenate(out).astype(np.int64)

    def evaluate(self, u, u_n):
        return self._on_edges(CohesiveRP.evaluate(self, u, u_n), u)


def use_points(kind: str, rotation_stiffness: float) -> None:
    """Make the case builder give every cohesive set points of ``kind`` ('nodal': rockfrac's own)."""
    if kind == "nodal":
        build_module.cohesive_groups = nodal_groups
        return
    k = rotation_stiffness if kind == "mean+rotation" else 0.0

    def groups(section, points, mesh, name, path="<case>", fallback="none", junction=None):
        pts, m1, p1 = edge_points(mesh.nodes, points.segments)
        law, eta = law_of_section(section), section.viscosity or 0.0
        if section.form is CohesiveForm.rp:
            return [EdgeRP(pts, m1, p1, law, section.augmentation, name, eta, k)]
        return [EdgeEP(pts, m1, p1, law, name, eta, k)]

    build_module.cohesive_groups = groups


def small_grains(form: str, steps: int, displacement: float, k: float, eta: float, runs: Path) -> dict:
    """The small grains specimen of benchmarks/README.md (12 x 24 mm, 4 grains, 2 mm quads), viscous,
    load control; EP's kn = kt = RP's augmentation = k."""
    d = grains_case(0.002, runs)
    d["mesh"].update(width=0.012, height=0.024, n_grains=4)
    d["output"] = {"vtk": False, "picture": False, "points": False}
    st = d["stages"][0]
    st.update(steps=steps, control="load")
    st.pop("max_steps")
    st["displacement"]["top"]["y"] = -displacement
    st["stop"]["below_peak_fraction"] = 0.05
    for c in d["cohesive"]:
        c.update(form=form, viscosity=eta)
        if form == "rp":
            c.pop("kn")
            c.pop("kt")
            c["augmentation"] = k
        else:
            c["kn"] = c["kt"] = k
    return d


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", nargs="+", default=["nodal", "mean", "mean+rotation"],
                    choices=["nodal", "mean", "mean+rotation"])
    ap.add_argument("--forms", nargs="+", default=["ep", "rp"], choices=["ep", "rp"])
    ap.add_argument("--steps", type=int, default=50)
    ap.add_argument("--displacement", type=float, default=4e-4, help="the top's shortening [m]")
    ap.add_argument("--k", type=float, default=2e12, help="EP's kn = kt, RP's augmentation, the moment's k [Pa/m]")
    ap.add_argument("--viscosity", type=float, default=2.5e-5)
    args = ap.parse_args()
    print("| points | form | steps | wall [s] | ended | " + " | ".join(f"R_top_y at {f}" for f in FRACTIONS)
          + " | D [J/m] |")
    print("|---" * (6 + len(FRACTIONS)) + "|")
    with tempfile.TemporaryDirectory() as tmp:
        for kind in args.points:
            use_points(kind, args.k)
            for form in args.forms:
                out = Path(tmp) / f"{kind}_{form}"
                case = small_grains(form, args.steps, args.displacement, args.k, args.viscosity, Path(tmp))
                t0 = time.perf_counter()
                s = run_case(parse_case(case, "<edge_points>"), out)
                wall = time.perf_counter() - t0
                rows = list(csv.DictReader(open(out / "history.csv")))
                lam = np.array([float(r["load_factor"]) for r in rows])
                at = []
                for f in FRACTIONS:
                    i = int(np.argmin(np.abs(lam - f)))
                    at.append(f"{-float(rows[i]['R_top_y']):.0f}" if abs(lam[i] - f) < 0.02 else "-")
                ended = "stage done" if s.result.completed else f"stopped at {lam[-1]:.3f}"
                print(f"| {kind} | {form.upper()} | {s.result.steps} | {wall:.0f} | {ended} | " + " | ".join(at)
                      + f" | {float(rows[-1]['D_dissipated']):.4f} |", flush=True)


if __name__ == "__main__":
    main()
