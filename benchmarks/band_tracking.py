"""An oblique embedded band softening to zero strength: local against nonlocal crack tracking.

One command: ``.venv/bin/python benchmarks/band_tracking.py`` (about 5 minutes on 2 cores). The case
is issue 15's: the band example's rock (examples/band/band.toml) on 24 x 48 quads, a weak cell
column at the left edge 6-14 mm above the base, c_r = phi_r = 0, 8 mm of shortening under path
control. At its onset angle (about 56.4 deg) a straight band from the seed reaches the right edge
at about 70 mm, so the two blocks can slide apart; with no strength left the force tends to the
confinement times the width, 800 N/m. Reports per tracking rule: where the path ends, the spread of
its segments' angles, the final force, and the Mohr-Coulomb closed form of the band at its final
mean strengths (c, tan phi) (EDE_NOTES). Writes ``results/band_tracking.json`` and the table between
the ``band-tracking-table`` markers of README.md.
"""

from __future__ import annotations

import math
import os
import sys
import time
import tomllib
from pathlib import Path

import numpy as np

HERE = Path(__file__).parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))
from run import machine, markdown_table, publish  # noqa: E402  (after the sys.path line)

RULES = {"local": {"tracking": "local"}, "nonlocal (5 mm)": {"tracking": "nonlocal", "tracking_length": 0.005}}


def case(tracking: dict) -> dict:
    d = tomllib.loads((ROOT / "examples" / "band" / "band.toml").read_text())
    d["mesh"].update(nx=24, ny=48, inclusion=[0.0, 0.006, 0.00167, 0.014])
    d["embedded"].update(tracking)
    d["loading"].update(axial_displacement=8e-3, max_steps=2000)
    d["loading"].pop("stop_below_peak_fraction", None)
    d["output"] = {"vtk": False}
    return d


def closed_form(c: float, tphi: float, band_deg: float, p: float = 2e4, width: float = 0.04) -> float:
    """Axial force [N/m] that slides a band at band_deg under confinement p (EDE_NOTES)."""
    th = math.radians(90.0 - band_deg)  # the normal's angle from the lateral axis
    s, co = math.sin(th), math.cos(th)
    return width * (c + p * (s * co + tphi * co**2)) / (s * co - tphi * s**2)


def main() -> None:
    from rockfrac.case.schema import parse_case
    from rockfrac.output.csvout import read_csv
    from rockfrac.runner import run_case

    rows, record = [], {"machine": machine(), "load_start": os.getloadavg(), "rules": {}}
    for name, tracking in RULES.items():
        out = HERE / "results" / "runs" / f"band_{tracking['tracking']}"  # gitignored
        t0 = time.perf_counter()
        s = run_case(parse_case(case(tracking)), out, overwrite=True)
        wall = time.perf_counter() - t0
        emb = s.built.embeddeds
        seg = np.vstack([g.segments[g.localized()] for g in emb])
        d = seg[:, 1] - seg[:, 0]
        ang = np.degrees(np.arctan2(d[:, 1], d[:, 0])) % 180.0
        top = seg[..., 1].max()
        end = "right edge" if np.isclose(seg[..., 0].max(), 0.04) else f"top (y = {top * 1e3:.1f} mm)"
        st = np.vstack([g.e_state[g.localized()] for g in emb])
        recs = [g.records() for g in emb]
        c = float(np.mean(np.concatenate([r["c"] for r in recs])))
        tphi = float(np.mean(np.concatenate([r["tan_phi"] for r in recs])))
        h = read_csv(out / "history.csv")
        force = float(h["F_axial"][-1])
        band = float(np.median(ang))
        ref = closed_form(c, tphi, band)
        record["rules"][name] = {"cells": int(st.shape[0]), "end": end, "angle_min": float(ang.min()),
                                 "angle_max": float(ang.max()), "F_end": force, "F_closed_form": ref,
                                 "c": c, "tan_phi": tphi, "steps": int(s.result.steps), "wall_s": wall}
        rows.append([name, st.shape[0], end, f"{ang.min():.1f}-{ang.max():.1f}", f"{force:.0f}",
                     f"{ref:.0f}", f"{force / ref:.2f}", s.result.steps, f"{wall:.0f}"])
    lines = markdown_table(["tracking", "cut cells", "path ends at", "segment angles [deg]", "F end [N/m]",
                            "closed form [N/m]", "ratio", "steps", "wall [s]"], rows)
    publish("band_tracking", record, lines)

if __name__ == "__main__":
    main()
