"""How a grown nodal band's force follows the mesh: 20 x 40 against 40 x 80 quads, one tracking length.

One command: ``.venv/bin/python benchmarks/band_growth.py`` (about 4 minutes on 2 cores). The case of
``band_meshes.py`` (the band example's rock with its weak column, c_r = phi_r = 0, softening rates
2000 /m, nonlocal tracking of length 6 mm, ``[embedded] kinematics = "nodal"``) at b = 0.1 and the
example's b. Reports per run where the band starts, how many cells it has at the peak, the peak and
where, the force at 1.5 and 2 mm, the holds (steps re-solved at the same load after cuts), and per b
the largest and the median relative difference of the two meshes' forces at equal displacement
after the later peak.
Writes ``results/band_growth.json`` and the ``band-growth-table`` of README.md.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).parent
sys.path.insert(0, str(HERE))
from band_meshes import LENGTH, meshes, run_one  # noqa: E402
from run import machine, markdown_table, publish  # noqa: E402


def gaps(a: dict, b: dict) -> tuple[float, float]:
    """Largest and median relative force difference at equal displacement, from the later peak to
    the smaller of the two end displacements (100 points)."""
    curves = [(np.asarray(r["u"]), np.asarray(r["F"])) for r in (a, b)]
    start = max(u[np.argmax(f)] for u, f in curves)
    stop = min(u.max() for u, _ in curves)
    grid = np.linspace(start, stop, 101)[1:]
    values = []
    for u, f in curves:
        k = int(np.argmax(f))  # the branch after the peak, ordered by displacement
        order = np.argsort(u[k:], kind="stable")
        values.append(np.interp(grid, u[k:][order], f[k:][order]))
    v = np.array(values)
    gap = (v.max(axis=0) - v.min(axis=0)) / v.min(axis=0)
    return float(gap.max()), float(np.median(gap))


def main() -> None:
    tmp = HERE / "results" / "runs"  # gitignored
    tmp.mkdir(parents=True, exist_ok=True)
    record: dict = {"machine": machine(), "load_start": os.getloadavg(), "length": LENGTH, "runs": {}, "gaps": {}}
    rows = []
    chosen = {k: v for k, v in meshes(tmp).items() if k.startswith("quad")}
    for b in (0.1, 0.321597):
        runs = []
        for name, (mesh, size) in chosen.items():
            r = run_one(mesh, size, b, tmp / f"growth_b{b}_{name.replace(' ', '_')}", kinematics="nodal",
                        tracking_length=LENGTH)
            u, f, cut = np.asarray(r["u"]), np.asarray(r["F"]), np.asarray(r["cut"])
            k, first = int(np.argmax(f)), int(np.argmax(cut > 0))
            at = {x: float(np.interp(x, u[k:][np.argsort(u[k:])], f[k:][np.argsort(u[k:])])) for x in (1.5e-3, 2e-3)}
            runs.append(r)
            record["runs"][f"b={b} {name}"] = {key: v for key, v in r.items() if key not in ("u", "F", "cut")} | {
                "u_onset": float(u[first]), "u_peak": float(u[k]), "cut_at_peak": int(cut[k]), "F_at": at}
            rows.append([f"{b:g}", name, f"{u[first] * 1e3:.3f}", f"{u[k] * 1e3:.3f}", f"{f[k]:.0f}", int(cut[k]),
                         r["cells"], f"{at[1.5e-3]:.0f}", f"{at[2e-3]:.0f}", f"{r['F_end']:.0f}", r["holds"],
                         r["steps"], f"{r['wall_s']:.0f}"])
        record["gaps"][f"b={b}"] = gaps(*runs)
    lines = markdown_table(["b", "mesh", "band starts at [mm]", "peak at [mm]", "F peak [N/m]", "cut cells at peak",
                            "cut cells", "F at 1.5 mm [N/m]", "F at 2 mm [N/m]", "F end [N/m]", "holds", "steps",
                            "wall [s]"], rows)
    lines += ["", "Post-peak forces of the two meshes at equal displacement, largest / median difference: "
              + ", ".join(f"{k}: {100 * v[0]:.1f} / {100 * v[1]:.1f} %" for k, v in record["gaps"].items())]
    publish("band_growth", record, lines)


if __name__ == "__main__":
    main()
