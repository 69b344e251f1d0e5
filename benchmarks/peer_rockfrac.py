"""rockfrac side of the peer benchmark: an EP CSE along the block's crack curve, through a case.

Run with rockfrac's virtualenv: ``peer_rockfrac.py MESH.msh N [--profile FILE] [--refine K]
[--work-rule trapezoidal|backward_euler]``; prints one JSON line. ``--refine K`` runs K times as
many steps, K times smaller; ``--work-rule`` is the law's (default trapezoidal: second order in
the step; backward Euler, the paper's, is first order). The case is what ``rockfrac run`` reads (kind = "gmsh", cohesive where = "curves"), built
by ``rockfrac.case.build`` and stepped by ``rockfrac.solve.stepping.run_stages`` as ``rockfrac
run`` does, with ``linear = "auto"``. An untimed run on a 4 x 4 block first loads the Numba
kernels (their cache) in this process; its time is reported as ``warmup_s``.
"""

from __future__ import annotations

import json
import math
import resource
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).parent
sys.path.insert(0, str(HERE))
import peer_mesh  # noqa: E402
import peer_problem as P  # noqa: E402


def case_dict(mesh_file: str, work_rule: str = "trapezoidal") -> dict:
    """The case: Table-1 style law reduced to pure opening (see peer_problem's docstring)."""
    return {
        "title": "peer benchmark: mode I block",
        "mesh": {"kind": "gmsh", "file": str(mesh_file), "element": "tri3",
                 "width": P.WIDTH, "height": P.HEIGHT},
        "bulk": {"E": P.E, "nu": P.NU},
        "cohesive": {
            "form": "ep", "where": "curves", "curves": ["crack"], "kn": P.KN, "kt": P.KT,
            "GfI": P.G_C, "GfII": P.G_C, "chi_p": P.SIGMA_C, "chi_r": 0.0,
            # cohesion and friction only shape the shear side of the yield surface: held constant
            "c_p": 2.0 * P.SIGMA_C, "c_r": 2.0 * P.SIGMA_C, "phi_p": math.radians(30.0),
            "phi_r": math.radians(30.0), "psi_p": math.radians(5.0),
            "alpha_chi": P.ALPHA_CHI, "alpha_c": 0.0, "alpha_phi": 0.0, "alpha_psi": 0.0,
            "work_rule": work_rule,
        },
        "loading": {"confinement": 0.0, "axial_displacement": -P.step_displacements()[-1],
                    "axial_steps": P.STEPS, "control": "displacement", "support": "bottom",
                    "pin": "pins", "axial": "top", "pressure": []},
        "output": {"points": False},
        "solver": {"linear": "auto", "tol_residual": P.TOL_RESIDUAL},
    }


def run(mesh_file: str, n: int, work_rule: str = "trapezoidal") -> dict:
    """Build and load the block; set-up and loading times, Newton iterations, top forces [N/m]."""
    from rockfrac.case.build import build
    from rockfrac.case.schema import parse_case
    from rockfrac.runner import history_row
    from rockfrac.solve import stepping
    from rockfrac.solve.linear import make_solver
    from rockfrac.solve.newton import NewtonOptions
    from rockfrac.solve.stepping import SteppingOptions

    case = parse_case(case_dict(mesh_file, work_rule), mesh_file)
    t0 = time.perf_counter()
    built = build(case, mesh_file)
    setup = time.perf_counter() - t0
    sol = case.solver
    newton = NewtonOptions(sol.max_iterations, sol.tol_residual, sol.tol_energy,
                           force_scale=1e-6 * P.E * P.WIDTH)
    options = SteppingOptions(cutback=sol.cutback, min_step=sol.min_step)
    stats = {"assembly": 0.0, "solve": 0.0, "iterations": 0, "calls": 0}
    original = stepping.newton_step

    def counted(*args, **kwargs):  # every Newton solve, failed attempts included
        res = original(*args, **kwargs)
        stats["assembly"] += res.time_assembly
        stats["solve"] += res.time_solve
        stats["iterations"] += res.iterations
        stats["calls"] += 1
        return res

    rows = []
    solver = make_solver(sol.linear.value)
    stepping.newton_step = counted
    try:
        t1 = time.perf_counter()
        result = stepping.run_stages(built.model, built.stages, solver, newton, options,
                                     lambda info: rows.append(history_row(built, info, None)))
        loading = time.perf_counter() - t1
    finally:
        stepping.newton_step = original
    axial = [r for r in rows if r["stage"].startswith("axial")]
    confinement_its = sum(r["newton_iterations"] for r in rows if not r["stage"].startswith("axial"))
    return {"code": "rockfrac", "work_rule": work_rule, "N": n, "dofs": int(built.model.n_dofs),
            "cohesive_elements": int(built.mesh.interfaces.shape[0]), "setup_s": setup,
            "loading_s": loading, "steps": len(axial), "stop": result.message,
            "newton_iterations": stats["iterations"], "newton_calls": stats["calls"],
            "confinement_iterations": confinement_its,
            "iterations_per_step": [r["newton_iterations"] for r in axial],
            "assembly_s": stats["assembly"], "solve_s": stats["solve"],
            "u_top": [-r["u_axial"] for r in axial], "force": [-r["F_axial"] for r in axial],
            "linear_solver": type(solver).__name__,
            "peak_rss_gib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20}


def main() -> None:
    mesh_file, n = sys.argv[1], int(sys.argv[2])
    if "--refine" in sys.argv:
        k = int(sys.argv[sys.argv.index("--refine") + 1])
        P.STEPS, P.STEPS_TO_PEAK = k * P.STEPS, k * P.STEPS_TO_PEAK
    rule = sys.argv[sys.argv.index("--work-rule") + 1] if "--work-rule" in sys.argv else "trapezoidal"
    t0 = time.perf_counter()
    warm = Path(mesh_file).with_name("warmup_4.msh")
    peer_mesh.write_block(warm, 4, P.WIDTH, P.HEIGHT)
    run(str(warm), 4, rule)
    warmup = time.perf_counter() - t0
    if "--profile" in sys.argv:
        import cProfile

        prof = cProfile.Profile()
        r = prof.runcall(run, mesh_file, n, rule)
        prof.dump_stats(sys.argv[sys.argv.index("--profile") + 1])
    else:
        r = run(mesh_file, n, rule)
    r["warmup_s"] = warmup
    print(json.dumps(r))


if __name__ == "__main__":
    main()
