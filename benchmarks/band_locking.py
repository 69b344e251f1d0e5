"""Where a grown embedded band's excess force passes: the cut cells' nodal forces split by stress part.

One command: ``.venv/bin/python benchmarks/band_locking.py`` (about a minute). The case is
``tests/test_crack_tracking.py``'s: the band example's rock with a weak seed at the left edge,
c_r = phi_r = 0, and nonlocal tracking. It runs on 12 x 24, 24 x 48 and 48 x 96 quads. The band
crosses to the right edge and, with no strength left, the continuum's answer is F = p w (800 N/m)
whatever the blocks' stresses (benchmarks/README.md, "Embedded band tracking").

At the end of each run, every cut cell's force on its + nodes, int sigma grad f_S dV, is summed
over the band. Its vertical component is the whole axial force: the only elements joining the two
blocks are the cut cells, so this is a check. It is split, with grad f_S = n (n . grad f_S) +
t (t . grad f_S), into two parts:
- the **traction part**, (sigma n)(n . grad f_S): what a band transmits through its traction;
- the **staircase part**, (sigma t)(t . grad f_S): the stress along the band, carried across it
  because grad f_S of a cell cut on a staircase is not along n. Its sigma_tt share is also reported.

Writes ``results/band_locking.json`` and the table between the ``band-locking-table`` markers of
README.md.
"""

from __future__ import annotations

import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent / "tests"))
from run import machine, markdown_table, publish  # noqa: E402
from test_crack_tracking import H, W, band_case  # noqa: E402

CONFINEMENT = 2e4  # [Pa], band_case's


def stress_tensors(voigt: np.ndarray) -> np.ndarray:
    """(..., 2, 2) in-plane stress tensors [Pa] from Voigt 6-vectors (xx, yy, zz, xy, yz, xz)."""
    s = np.zeros(voigt.shape[:-1] + (2, 2))
    s[..., 0, 0], s[..., 1, 1] = voigt[..., 0], voigt[..., 1]
    s[..., 0, 1] = s[..., 1, 0] = voigt[..., 3]
    return s


def band_forces(groups) -> dict[str, np.ndarray]:
    """The cut cells' summed force on their + nodes [N/m] (x, y) and its parts (module note)."""
    from rockfrac.elements.ede_kernel import E_LOC, E_N, E_T

    out = {k: np.zeros(2) for k in ("total", "traction", "staircase", "staircase_tt")}
    for g in groups:
        cut = np.flatnonzero(g.e_state[:, E_LOC] > 0)
        sigma = stress_tensors(g.sigma[cut])  # committed, at the Gauss points
        n, t = g.e_state[cut, E_N:E_N + 2], g.e_state[cut, E_T:E_T + 2]
        grad, w = g.gradf[cut][..., :2], g.wdet[cut]
        n_grad, t_grad = np.einsum("cqj,cj->cq", grad, n), np.einsum("cqj,cj->cq", grad, t)
        s_n, s_t = np.einsum("cqij,cj->cqi", sigma, n), np.einsum("cqij,cj->cqi", sigma, t)
        out["total"] += np.einsum("cqij,cqj,cq->i", sigma, grad, w)
        out["traction"] += np.einsum("cqi,cq,cq->i", s_n, n_grad, w)
        out["staircase"] += np.einsum("cqi,cq,cq->i", s_t, t_grad, w)
        out["staircase_tt"] += np.einsum("cqi,ci,cq,cq,ck->k", s_t, t, t_grad, w, t)
    return out


def run(nx: int) -> dict:
    from rockfrac.case.schema import parse_case
    from rockfrac.output.csvout import read_csv
    from rockfrac.runner import run_case

    mesh = {"kind": "block", "element": "quad4", "width": W, "height": H, "nx": nx, "ny": 2 * nx,
            "inclusion": [0.0, 0.0067, 0.0034, 0.0167]}
    out = Path(tempfile.mkdtemp())
    t0 = time.perf_counter()
    s = run_case(parse_case(band_case(mesh, {"tracking": "nonlocal", "tracking_length": 0.01})), out)
    wall = time.perf_counter() - t0
    force = float(read_csv(out / "history.csv")["F_axial"][-1])
    parts = band_forces(s.built.embeddeds)
    cut = sum(int(np.count_nonzero(g.localized())) for g in s.built.embeddeds)
    assert abs(-parts["total"][1] - force) <= 1e-6 * force, "the cut cells must carry the whole axial force"
    return {"mesh": f"{nx} x {2 * nx}", "completed": bool(s.result.completed), "cut_cells": cut, "F_end": force,
            **{k: (-v[1]) for k, v in parts.items()}, "wall_s": wall}


def main() -> None:
    record = {"machine": machine(), "load_start": os.getloadavg(), "rows": [run(nx) for nx in (12, 24, 48)]}
    pw = CONFINEMENT * W
    rows = [[r["mesh"], r["cut_cells"], f"{r['F_end']:.0f}", f"{pw:.0f}", f"{r['traction']:.0f}",
             f"{r['traction'] / pw:.3f}", f"{r['staircase']:.0f}", f"{r['staircase_tt']:.0f}",
             f"{r['wall_s']:.0f}"] for r in record["rows"]]
    lines = markdown_table(["mesh", "cut cells", "F end [N/m]", "p w [N/m]", "traction part [N/m]",
                            "traction / p w", "staircase part [N/m]", "of it sigma_tt [N/m]", "wall [s]"], rows)
    publish("band_locking", record, lines)


if __name__ == "__main__":
    main()
