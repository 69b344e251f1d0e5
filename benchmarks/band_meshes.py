"""Oblique embedded bands softening to zero strength on three meshes, at two band angles, with both
kinematics of the embedded crack (``[embedded] kinematics``: "elemental", the paper's constant jump
per cell; "nodal", the jump a nodal field and the cut cells' two sides apart, penalty kn = kt = 1e10
Pa/m, about E / h).

One command: ``.venv/bin/python benchmarks/band_meshes.py`` (about 40 minutes on 2 cores). The band
example's rock with its weak column at the left edge (6-14 mm above the base), c_r = phi_r = 0,
softening rates 2000 /m, 4 mm of shortening under path control, nonlocal tracking with a Gaussian
length of 6 mm on every mesh; meshes: 20 x 40 and 40 x 80 quads and an unstructured Gmsh triangle
mesh (2 mm, the same weak column); band angles: the example's dilatancy b (bands near 56 deg) and
b = 0.1 (steeper). For each
run: where the path ends, its angle spread, the final force against the Mohr-Coulomb closed form of
the band at its final mean strengths (800 N/m with none left), and per angle the largest difference
between the meshes' post-peak curves at equal top displacement. The same rock with the band given
from the start ([[embedded.cracks]], the grown band's first and last points) is the reference
without growth. Writes ``results/band_meshes.json`` and the ``band-meshes-table`` of README.md.
"""

from __future__ import annotations

import math
import os
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(ROOT / "tests"))
from band_tracking import case as band_case  # noqa: E402
from band_tracking import closed_form  # noqa: E402
from run import machine, markdown_table, publish  # noqa: E402

W, H = 0.04, 0.08
LENGTH = 0.006  # [m]: the nonlocal tracking length, one on every mesh


def meshes(tmp: Path) -> dict[str, tuple[dict, float]]:
    """name -> ([mesh] section, cell size [m])."""
    from test_crack_tracking import triangle_block

    seed = [0.0, 0.006, 0.002, 0.014]
    msh = triangle_block(tmp / "tri.msh", 0.002, tuple(seed))
    return {"quad 20x40": ({"kind": "block", "element": "quad4", "width": W, "height": H, "nx": 20, "ny": 40,
                            "inclusion": seed}, W / 20),
            "quad 40x80": ({"kind": "block", "element": "quad4", "width": W, "height": H, "nx": 40, "ny": 80,
                            "inclusion": seed}, W / 40),
            "tri 2 mm": ({"kind": "gmsh", "file": str(msh)}, 0.002)}


KINEMATICS = {"elemental": {}, "nodal": {"kinematics": "nodal", "kn": 1e10, "kt": 1e10}}


def run_one(mesh: dict, size: float, b: float, out: Path, crack: list | None = None, kinematics: str = "elemental",
            tracking_length: float | None = None):
    """One run; tracking_length [m] defaults to 3 cell sizes."""
    from rockfrac.case.schema import parse_case
    from rockfrac.output.csvout import read_csv
    from rockfrac.runner import run_case

    d = band_case({"tracking": "nonlocal", "tracking_length": tracking_length or 3 * size})
    d["mesh"] = mesh
    for m in d["materials"]:
        m["b"] = b
    d["embedded"].update(alpha_c=2e3, alpha_phi=2e3, alpha_psi=2e3, **KINEMATICS[kinematics])
    d["loading"].update(axial_displacement=4e-3, path_increment=1e-5, max_steps=1500)
    if crack is not None:
        d["embedded"].update(cracks=[{"points": crack, "c_p": 8000.0}], tracking="local")  # max_cracks = 1:
        d["embedded"].pop("tracking_length")  # the given crack is the only one
    t0 = time.perf_counter()
    s = run_case(parse_case(d), out, overwrite=True)
    wall = time.perf_counter() - t0
    emb = s.built.embeddeds
    seg = np.vstack([g.segments[g.localized()] for g in emb])
    dd = seg[:, 1] - seg[:, 0]
    ang = np.degrees(np.arctan2(dd[:, 1], dd[:, 0])) % 180.0
    recs = [g.records() for g in emb]
    c = float(np.mean(np.concatenate([r["c"] for r in recs])))
    tphi = float(np.mean(np.concatenate([r["tan_phi"] for r in recs])))
    h = read_csv(out / "history.csv")
    reach = "right edge" if np.isclose(seg[..., 0].max(), W) else f"x = {seg[..., 0].max() * 1e3:.1f} mm"
    ends = seg.reshape(-1, 2)
    first, last = ends[np.argmin(ends[:, 0])], ends[np.argmax(ends[:, 0])]
    return {"cells": int(seg.shape[0]), "reach": reach, "angle_min": float(ang.min()), "angle_max": float(ang.max()),
            "angle_median": float(np.median(ang)), "F_end": float(h["F_axial"][-1]),
            "F_closed_form": closed_form(c, tphi, float(np.median(ang))), "F_peak": float(h["F_axial"].max()),
            "steps": int(s.result.steps), "completed": bool(s.result.completed), "wall_s": wall,
            "ends": [first.tolist(), last.tolist()],
            "u": h["u_axial"].tolist(), "F": h["F_axial"].tolist(), "cut": h["n_localized"].tolist(),
            "holds": int(np.sum(h["control"] == "hold"))}


def post_peak_gap(runs: list[dict]) -> float:
    """Largest relative difference of the force between the runs at equal top displacement after the
    latest peak, over the displacements all of them reached."""
    curves = [(np.asarray(r["u"]), np.asarray(r["F"])) for r in runs]
    start = max(u[np.argmax(f)] for u, f in curves)
    stop = min(u.max() for u, _ in curves)
    if stop <= start:
        return math.nan
    grid = np.linspace(start, stop, 50)[1:]
    values = np.array([np.interp(grid, u[np.argsort(u)], f[np.argsort(u)]) for u, f in curves])
    return float(np.max((values.max(axis=0) - values.min(axis=0)) / values.min(axis=0)))


def aligned_gaps(runs: list[dict]) -> tuple[float, float]:
    """The post-peak curves shifted to a common peak displacement (F against u - u_peak, from where
    each snap-back ends): the largest and the median relative difference between the runs. The
    displacement at which the band forms (the end of the hardening plateau) shifts with the mesh;
    this compares the softening that follows."""
    branches = []
    for r in runs:
        u, f = np.asarray(r["u"]), np.asarray(r["F"])
        k = int(np.argmax(f))
        j = k + int(np.argmin(u[k:]))  # the snap-back's end: from there u grows
        branches.append((u[j:] - u[k], f[j:]))
    lo, hi = max(x[0] for x, _ in branches), min(x[-1] for x, _ in branches)
    if hi <= lo:
        return math.nan, math.nan
    grid = np.linspace(lo, hi, 80)
    values = np.array([np.interp(grid, x, f) for x, f in branches])
    gap = (values.max(axis=0) - values.min(axis=0)) / values.min(axis=0)
    return float(gap.max()), float(np.median(gap))


def main() -> None:
    tmp = HERE / "results" / "runs"
    tmp.mkdir(parents=True, exist_ok=True)
    record: dict = {"machine": machine(), "load_start": os.getloadavg(), "runs": {}, "post_peak_gap": {},
                    "aligned_gap": {}}
    rows = []
    for kin in KINEMATICS:
        for b in (0.321597, 0.1):
            grown = []
            for name, (mesh, size) in meshes(tmp).items():
                tag = f"{kin}_b{b}_{name.replace(' ', '_')}"
                r = run_one(mesh, size, b, tmp / f"band_{tag}", kinematics=kin, tracking_length=LENGTH)
                given = run_one(mesh, size, b, tmp / f"crack_{tag}", crack=r["ends"], kinematics=kin)
                grown.append(r)
                for kind, x in (("grown", r), ("given", given)):
                    record["runs"][f"{kin} b={b} {name} {kind}"] = {k: v for k, v in x.items() if k not in ("u", "F", "cut")}
                    rows.append([kin, f"{b:g}", name, kind, x["cells"], x["reach"],
                                 f"{x['angle_min']:.1f}-{x['angle_max']:.1f}", f"{x['F_peak']:.0f}",
                                 f"{x['F_end']:.0f}", f"{x['F_closed_form']:.0f}",
                                 f"{x['F_end'] / x['F_closed_form']:.3f}", x["steps"], f"{x['wall_s']:.0f}"])
            record["post_peak_gap"][f"{kin} b={b}"] = post_peak_gap(grown)
            record["aligned_gap"][f"{kin} b={b}"] = aligned_gaps(grown)
            print(f"{kin}, b = {b}: post-peak curves of the grown bands within "
                  f"{100 * record['post_peak_gap'][f'{kin} b={b}']:.1f} %; aligned at their peaks: largest "
                  f"{100 * record['aligned_gap'][f'{kin} b={b}'][0]:.1f} %, median "
                  f"{100 * record['aligned_gap'][f'{kin} b={b}'][1]:.1f} %")
    lines = markdown_table(["kinematics", "b", "mesh", "band", "cut cells", "path reaches", "angles [deg]",
                            "F peak [N/m]", "F end [N/m]", "closed form [N/m]", "ratio", "steps", "wall [s]"], rows)
    lines += ["", "Post-peak curves of the three grown meshes at equal displacement, largest difference: " +
              ", ".join(f"{k}: {100 * v:.1f} %" for k, v in record["post_peak_gap"].items()),
              "", "The same curves shifted to a common peak displacement (the softening after the band forms), "
              "largest / median difference: " + ", ".join(f"{k}: {100 * v[0]:.1f} / {100 * v[1]:.1f} %"
                                                          for k, v in record["aligned_gap"].items())]
    publish("band_meshes", record, lines)

if __name__ == "__main__":
    main()
