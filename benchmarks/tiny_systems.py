"""Tiny systems: dense LU (LAPACK getrf/getrs) against PARDISO per factorization + solve, and the
crossover that sets ``rockfrac.solve.linear.DENSE_UP_TO``.

One command: ``.venv/bin/python benchmarks/tiny_systems.py``. Systems: the constrained tangents
(first Newton iteration) of the paper's three cases (RP CSE 20 dofs, EP CSE 16, EDE hexahedron 24)
and of elastic N x N blocks (2 (N+1)^2 dofs). Each backend factorizes and solves the same system
``--calls`` times (default 2000, fewer above 500 dofs); best of 3 repetitions, per call. Writes
``results/tiny_systems.json`` and the table between the ``tiny-table`` markers of README.md.
"""

from __future__ import annotations

import json
import os
import sys
import time
from pathlib import Path

import numpy as np
import scipy.sparse as sp

HERE = Path(__file__).parent
sys.path.insert(0, str(HERE))
from run import machine, markdown_table, replace_table  # noqa: E402  (after the sys.path line)


def tangent(case: dict) -> sp.csr_matrix:
    from rockfrac.case.build import build
    from rockfrac.case.schema import parse_case

    m = build(parse_case(case, "t.toml")).model
    u0 = m.initial_unknowns()
    a = sp.csr_matrix(m.apply_dirichlet(m.assemble(u0, u0, np.zeros(m.n_dofs)).matrix))
    a.sort_indices()
    return a


def per_call(solver, a: sp.csr_matrix, calls: int) -> float:
    b = np.ones(a.shape[0])
    for _ in range(3):
        solver.factorize(a).solve(b)
    best = np.inf
    for _ in range(3):
        t0 = time.perf_counter()
        for _ in range(calls):
            solver.factorize(a).solve(b)
        best = min(best, (time.perf_counter() - t0) / calls)
    return best


def main() -> None:
    from rockfrac.solve import linear
    from rockfrac.studies import table1

    systems = {"RP CSE (paper)": table1.cse_case("rp", axial_steps=4),
               "EP CSE (paper)": table1.cse_case("ep", 1e9, axial_steps=4),
               "EDE hexahedron (paper)": table1.ede_case(axial_steps=4)}
    for n in (4, 6, 8, 10, 14, 20):
        systems[f"elastic {n} x {n}"] = {"mesh": {"kind": "specimen", "crack": False, "nx": n, "ny": n},
                                         "bulk": {"E": 1.5e7, "nu": 0.3},
                                         "loading": {"confinement": 2e4, "axial_displacement": 1e-3, "axial_steps": 2}}
    rows = []
    for name, case in systems.items():
        a = tangent(case)
        calls = 2000 if a.shape[0] <= 500 else 200
        dense = linear.Pardiso()
        dense.dense_up_to = 10**9
        sparse = linear.Pardiso()
        sparse.dense_up_to = 0
        td, ts = per_call(dense, a, calls), per_call(sparse, a, calls)
        x = dense.factorize(a).solve(np.ones(a.shape[0]))
        y = sparse.factorize(a).solve(np.ones(a.shape[0]))
        rows.append({"system": name, "dofs": a.shape[0], "nnz": int(a.nnz), "dense_us": 1e6 * td,
                     "pardiso_us": 1e6 * ts, "max_rel_diff": float(np.abs(x - y).max() / np.abs(y).max())})
        print(rows[-1], flush=True)
    info = machine()
    info["load_average"] = os.getloadavg()
    (HERE / "results").mkdir(exist_ok=True)
    (HERE / "results" / "tiny_systems.json").write_text(json.dumps({"machine": info, "rows": rows}, indent=1))
    lines = [f"Machine: {info['cpu']}, {info['cores']} cores; {info['date']}; load average "
             f"{info['load_average'][0]:.2f}; `DENSE_UP_TO` = {linear.DENSE_UP_TO} rows.", "",
             ]
    lines += markdown_table(["system", "dofs", "dense LU [us / call]", "PARDISO [us / call]", "PARDISO / dense",
                             "max rel. difference"],
                            [[r["system"], r["dofs"], f"{r['dense_us']:.1f}", f"{r['pardiso_us']:.1f}",
                              f"{r['pardiso_us'] / r['dense_us']:.2f}", f"{r['max_rel_diff']:.1e}"] for r in rows])
    print("\n".join(lines))
    replace_table("tiny-table", lines)


if __name__ == "__main__":
    main()
