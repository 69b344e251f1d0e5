"""MPI scaling on this machine (issue 17): 1 and 2 ranks, a 2D and a 3D problem of 1e6 dofs.

One command: ``make mpi-scaling`` (``.venv-mpi/bin/python benchmarks/mpi_scaling.py``, about 40
minutes). Each run is its own ``mpiexec -n R`` (its own peak memory per rank):

- **2d**: a unit square of n x n quad4 cells, nonassociative Drucker-Prager, compressed along y by
  2 mm in 4 steps (it yields in the third), GMRES + GAMG ('petsc-gamg');
- **3d**: the same in a unit box of n^3 hex8 cells on rollers;
- **cohesive**: the paper's EP specimen (elastic blocks, the paper's law on the inclined crack,
  penalty 1e12 Pa/m) refined to 2.5e5 dofs; confinement, then 5 axial steps past the crack's
  activation (located as an event, then softening), MUMPS's parallel LU ('petsc'). At 1e6 dofs
  MUMPS's 2D factors outgrow this machine's 24 GiB (the serial run was killed at 24 GiB).
- **joints**: cohesive at 1e6 dofs: the 3D box (hex8) as a stack of four slabs with rigid-plastic
  joints on the three planes between them (augmented multipliers: saddle points), under a pressure
  on the top, then dragged sideways by 0.05 mm (3 steps), GMRES with the Schur field
  split ('petsc-gamg': GAMG on the displacements, MUMPS on the multipliers' selfp Schur block).

Rows: ``serial`` (rockfrac's serial engine with the same PETSc solver on one process: the overhead
of the distributed path is the ratio to the 1-rank row), then the distributed engine on 1 and 2
ranks: strong scaling (the same size on 1 and 2 ranks) and weak scaling (half the size on 1 rank).
Times: set-up (case to model: mesh, partition, groups, pattern, preallocation), assembly (every
residual and tangent, with the ranks' sums and the matrix's insertion), solve (factorizations and
solves), Newton iterations, the largest resident memory of a rank. Machine and load are recorded
with every row; results go to ``benchmarks/results/mpi_scaling.json`` and the "MPI scaling" table
of ``benchmarks/README.md``. ``--quick``: small sizes, prints only. ``--held``: set-up only, on 2
ranks, the arrays each rank's mesh, partition and layout hold (a rank's piece of the mesh), for 2d,
3d, **embedded** (2d with tracked embedded cracks: the cells its crack-path registry sees) and
**nodal** (the same with nodal embedded cracks, half the cells: each node has its two enrichment
unknowns; the sides its enrichment registry knows).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent


DP = {"model": "drucker_prager", "E": 2e10, "nu": 0.25, "beta": 0.6, "b": 0.2, "kappa0": 1e7}
OUT = {"picture": False, "points": False}


def case_2d(dofs: float) -> dict:
    """A unit square of n x n quad4 cells, Drucker-Prager, compressed along y past its yield."""
    n = max(2, round((dofs / 2) ** 0.5) - 1)
    return {"title": "block", "mesh": {"kind": "block", "width": 1.0, "height": 1.0, "nx": n, "ny": n},
            "bulk": DP, "stages": [{"name": "press", "steps": 4,
                                    "displacement": {"bottom": {"y": 0.0}, "bottom_left": {"x": 0.0},
                                                     "top": {"y": -2e-3}}}],
            "solver": {"linear": "petsc-gamg"}, "output": OUT}


def case_embedded(dofs: float) -> dict:
    """case_2d with embedded strong discontinuities in its Drucker-Prager cells, tracked ("local"),
    softening as the band example's (set-up only: ``--held``)."""
    case = case_2d(dofs)
    case["embedded"] = {"c_p": "eq28", "c_r": 0.0, "phi_p": 0.5236, "phi_r": 0.0, "psi_p": 0.087, "alpha_c": 5e3,
                        "alpha_phi": 5e3, "alpha_psi": 5e3, "tracking": "local"}
    case["solver"] = {"linear": "petsc"}
    return case


def case_nodal(dofs: float) -> dict:
    """case_embedded with nodal cracks: half its cells, so that with the enrichment unknowns (two a
    node) the model has about ``dofs`` unknowns (set-up only: ``--held``)."""
    case = case_embedded(dofs / 2)
    case["embedded"].update(kinematics="nodal", kn=1e10, kt=1e10)
    return case


def case_cohesive(dofs: float) -> dict:
    """The paper's EP specimen (two blocks of nx x 2 nx cells, the paper's law on the inclined crack,
    penalty 1e12 Pa/m) with about ``dofs`` unknowns: confinement, 5 axial steps past the activation."""
    sys.path.insert(0, str(ROOT / "tests"))
    from conftest import paper_case

    nx = max(2, round((dofs / 8) ** 0.5))
    case = paper_case("ep", 1e12, axial_steps=5, axial_displacement=0.5e-3)
    case["mesh"].update(nx=nx, ny=2 * nx)
    case["solver"] = {"linear": "petsc"}
    case["output"] = OUT
    return case


def case_joints(dofs: float, folder: Path) -> dict:
    """The 3D stack of four slabs with RP joints between them (about ``dofs`` unknowns): pressed,
    then its top dragged sideways by 0.05 mm."""
    from rockfrac.mesh import rock_tests as rt

    n = max(4, 4 * round((round((dofs / 3) ** (1 / 3)) - 1) / 4))
    msh = rt.box(folder / "stack.msh", (1.0, 1.0, 1.0), (n, n, n), element="hex8", layers=4)
    law = {"GfI": 50.0, "GfII": 500.0, "chi_p": 1e6, "chi_r": 0.0, "c_p": 2e6, "c_r": 0.0, "phi_p": 0.6,
           "phi_r": 0.5, "psi_p": 0.1, "alpha_chi": 5.0, "alpha_c": 5.0, "alpha_phi": 5.0, "alpha_psi": 5.0}
    held = {"bottom": {"x": 0.0, "y": 0.0, "z": 0.0}}
    return {"title": "stack", "mesh": {"kind": "gmsh", "file": str(msh)}, "bulk": {"E": 2e10, "nu": 0.25},
            "cohesive": {"where": "boundaries", "form": "rp", "augmentation": 1e12, **law},
            "stages": [{"name": "press", "displacement": held, "pressure": {"top": 1e6}},
                       {"name": "drag", "steps": 2, "pressure": {"top": 1e6},
                        "displacement": dict(held, top={"x": 5e-5, "y": 0.0})}],
            "solver": {"linear": "petsc-gamg"}, "output": OUT}


def case_3d(dofs: float, folder: Path) -> dict:
    from rockfrac.mesh import rock_tests as rt

    n = max(2, round((dofs / 3) ** (1 / 3)) - 1)
    msh = rt.box(folder / "box.msh", (1.0, 1.0, 1.0), (n, n, n), element="hex8")
    return {"title": "box", "mesh": {"kind": "gmsh", "file": str(msh)},
            "bulk": DP, "stages": [{"name": "press", "steps": 4, "displacement": {"left": {"x": 0.0}, "front": {"y": 0.0},
                                                                      "bottom": {"z": 0.0}, "top": {"z": -2e-3}}}],
            "solver": {"linear": "petsc-gamg"}, "output": OUT}


def child(problem: str, dofs: float, serial: bool, out: Path) -> None:
    """One run (under mpiexec unless serial): its numbers into ``out`` (rank 0)."""
    import numpy as np

    from rockfrac.case.build import build
    from rockfrac.case.schema import parse_case
    from rockfrac.runner import engine_options
    from rockfrac.solve.linear import make_solver
    from rockfrac.solve.stepping import run_stages

    folder = Path(tempfile.mkdtemp())
    comm = None
    if not serial:
        from mpi4py import MPI

        comm = MPI.COMM_WORLD
    if comm is None or comm.rank == 0:
        case = ({"2d": case_2d, "cohesive": case_cohesive}[problem](dofs) if problem in ("2d", "cohesive")
                else {"3d": case_3d, "joints": case_joints}[problem](dofs, folder))
    else:
        case = None
    if comm is not None:
        case = comm.bcast(case, root=0)
    case_obj = parse_case(case, problem)
    t0 = time.perf_counter()
    if serial:
        built = build(case_obj)
        solver = make_solver(case["solver"]["linear"], built.mesh.nodes, built.model.n_dofs)
    else:
        from rockfrac.parallel.run import build_distributed
        from rockfrac.parallel.solvers import distributed_solver

        built = build_distributed(case_obj, comm)
        solver = distributed_solver(case["solver"]["linear"])
    t_setup = time.perf_counter() - t0
    stats = {"assembly": 0.0, "solve": 0.0, "iterations": 0, "steps": 0}

    def on_step(info) -> None:
        stats["assembly"] += info.newton.time_assembly
        stats["solve"] += info.newton.time_solve
        stats["iterations"] += info.newton.iterations
        stats["steps"] += 1

    newton, stepping = engine_options(built)
    t0 = time.perf_counter()
    result = run_stages(built.model, built.stages, solver, newton, stepping, on_step,  # type: ignore[arg-type]
                        u0=built.program.u0, f0=built.program.f0)
    t_run = time.perf_counter() - t0
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20  # GiB (ru_maxrss in KiB)
    ranks = 1 if comm is None else comm.Get_size()
    rss_all = [rss] if comm is None else comm.gather(rss, root=0)
    local = {"assembly": stats["assembly"], "solve": stats["solve"]}
    if comm is not None:
        local = {k: comm.allreduce(v, op=MPI.MAX) for k, v in local.items()}  # the slowest rank's
    u_norm = float(np.linalg.norm(built.model.gather(result.u)))  # collective: on every rank
    if comm is None or comm.rank == 0:
        row = {"problem": problem, "engine": "serial" if serial else "distributed", "ranks": ranks,
               "dofs": int(built.model.n_dofs_global), "completed": bool(result.completed), "message": result.message,
               "steps": stats["steps"], "newton_iterations": stats["iterations"], "setup_s": round(t_setup, 2),
               "assembly_s": round(local["assembly"], 2), "solve_s": round(local["solve"], 2),
               "run_s": round(t_run, 2), "rss_gib_per_rank": [round(r, 2) for r in rss_all],
               "solver": case["solver"]["linear"], "u_norm": u_norm}
        out.write_text(json.dumps(row))
    shutil.rmtree(folder, ignore_errors=True)


def launch(problem: str, dofs: float, ranks: int, serial: bool, timeout: float) -> dict:
    out = Path(tempfile.mkdtemp()) / "row.json"
    me = [sys.executable, str(Path(__file__).resolve()), "--child", problem, str(dofs), str(out)]
    if serial:
        cmd = me + ["--serial"]
    else:
        cmd = [shutil.which("mpiexec") or "mpiexec", "-n", str(ranks)] + me
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               OMPI_MCA_rmaps_base_oversubscribe="1", OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1",
               NUMBA_NUM_THREADS="1")
    load = os.getloadavg()[0]
    t0 = time.perf_counter()
    try:
        done = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return {"problem": problem, "ranks": ranks, "engine": "serial" if serial else "distributed",
                "target_dofs": dofs, "failed": f"timeout after {timeout:.0f} s"}
    if done.returncode != 0 or not out.exists():
        return {"problem": problem, "ranks": ranks, "engine": "serial" if serial else "distributed",
                "target_dofs": dofs, "failed": (done.stderr or done.stdout)[-800:]}
    row = json.loads(out.read_text())
    row.update(wall_s=round(time.perf_counter() - t0, 2), load_before=round(load, 2),
               load_after=round(os.getloadavg()[0], 2))
    return row


PLAN = {  # problem -> [(dofs, ranks, serial)]: strong (the size on 1 and 2 ranks), weak (half on 1)
    "2d": [(1e6, 1, True), (1e6, 1, False), (1e6, 2, False), (5e5, 1, False)],
    "3d": [(1e6, 1, True), (1e6, 1, False), (1e6, 2, False), (5e5, 1, False)],
    "cohesive": [(2.5e5, 1, True), (2.5e5, 1, False), (2.5e5, 2, False)],
    "joints": [(1e6, 1, True), (1e6, 1, False), (1e6, 2, False), (5e5, 1, False)],
}


def _nbytes(obj, seen: set) -> int:
    """The bytes of the NumPy arrays reachable from obj through attributes, dicts, lists, tuples."""
    import numpy as np

    if id(obj) in seen:
        return 0
    seen.add(id(obj))
    if isinstance(obj, np.ndarray):
        return obj.nbytes
    if isinstance(obj, dict):
        return sum(_nbytes(v, seen) for v in obj.values())
    if isinstance(obj, (list, tuple)):
        return sum(_nbytes(v, seen) for v in obj)
    return sum(_nbytes(v, seen) for v in vars(obj).values()) if hasattr(obj, "__dict__") else 0


def held_child(problem: str, dofs: float, out: Path) -> None:
    """One rank of `--held`: build the case, then the arrays of its mesh, partition and layout [MiB]
    and its peak so far [GiB], every rank's row written by rank 0."""
    import numpy as np
    from mpi4py import MPI

    from rockfrac.case.schema import parse_case
    from rockfrac.elements.ede_nodal import NodalEmbeddedDruckerPrager
    from rockfrac.parallel.run import build_distributed

    comm = MPI.COMM_WORLD
    folder = Path(comm.bcast(tempfile.mkdtemp() if comm.rank == 0 else None, root=0))
    case = None
    if comm.rank == 0:
        make = {"2d": case_2d, "embedded": case_embedded, "nodal": case_nodal}.get(problem)
        case = make(dofs) if make is not None else case_3d(dofs, folder)
    built = build_distributed(parse_case(comm.bcast(case, root=0), problem), comm)
    seen: set = set()
    layout = built.model.layout  # type: ignore[attr-defined]
    paths = {id(g.paths): g.paths for g in built.embeddeds}.values()  # the crack-path registry
    registries = {id(g.registry): g.registry for g in built.embeddeds  # the nodal cracks' enrichment registry
                  if isinstance(g, NodalEmbeddedDruckerPrager)}.values()
    mine = {"rank": comm.rank, "piece_cells": built.mesh.cells.shape[0],
            "crack_cells_seen": sum(p.owner.shape[0] for p in paths),
            "crack_neighbour_lists": sum(len(p.nbr) for p in paths),
            "enrichment_sides": sum(len(r.side_cells) for r in registries),
            "mesh_mib": _nbytes(built.mesh, seen) / 2**20,
            "partition_mib": _nbytes(built.partition, seen) / 2**20,
            "layout_mib": _nbytes({k: v for k, v in vars(layout).items() if isinstance(v, np.ndarray)}, seen) / 2**20,
            "peak_after_setup_gib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20}
    rows = comm.gather({k: round(v, 2) for k, v in mine.items()}, root=0)
    if comm.rank == 0:
        out.write_text(json.dumps({"problem": problem, "dofs": int(built.model.n_dofs_global), "ranks": rows}))
        shutil.rmtree(folder, ignore_errors=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--child", nargs=3, metavar=("PROBLEM", "DOFS", "OUT"))
    ap.add_argument("--serial", action="store_true")
    ap.add_argument("--quick", action="store_true", help="small sizes, print only")
    ap.add_argument("--problems", nargs="+", default=["2d", "3d", "cohesive", "joints"])
    ap.add_argument("--timeout", type=float, default=3600.0)
    ap.add_argument("--held", action="store_true", help="2 ranks, set-up only: the arrays of each rank's "
                    "mesh, partition and layout, and its peak after set-up (2d, 3d, embedded, nodal)")
    ap.add_argument("--held-child", nargs=3, metavar=("PROBLEM", "DOFS", "OUT"))
    args = ap.parse_args()
    if args.child:
        child(args.child[0], float(args.child[1]), args.serial, Path(args.child[2]))
        return
    if args.held_child:
        held_child(args.held_child[0], float(args.held_child[1]), Path(args.held_child[2]))
        return
    if args.held:
        env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
        for problem in [p for p in args.problems if p in ("2d", "3d", "embedded", "nodal")]:
            out = Path(tempfile.mkdtemp()) / "held.json"
            subprocess.run([shutil.which("mpiexec") or "mpiexec", "-n", "2", sys.executable, str(Path(__file__).resolve()),
                            "--held-child", problem, str(1e6 / 50 if args.quick else 1e6), str(out)], env=env,
                           check=True, timeout=args.timeout)
            print(json.dumps(dict(json.loads(out.read_text()), date=time.strftime("%Y-%m-%d %H:%M"),
                                  load=round(os.getloadavg()[0], 2))))
        return
    machine = {"machine": platform.node(), "cpu": platform.processor() or platform.machine(),
               "cores": os.cpu_count(), "python": platform.python_version(), "date": time.strftime("%Y-%m-%d %H:%M")}
    rows = []
    for problem in args.problems:
        for dofs, ranks, serial in PLAN[problem]:
            row = launch(problem, dofs / 50 if args.quick else dofs, ranks, serial, args.timeout)
            row.update(machine)
            print(json.dumps(row), flush=True)
            rows.append(row)
    if not args.quick:
        path = HERE / "results" / "mpi_scaling.json"
        kept = [r for r in json.loads(path.read_text()) if r["problem"] not in args.problems] if path.exists() else []
        path.write_text(json.dumps(kept + rows, indent=1))
        print(f"written {path}")


if __name__ == "__main__":
    main()
