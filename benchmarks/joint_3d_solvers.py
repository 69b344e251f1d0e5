"""The jointed triaxial cylinder (examples/rock_tests/triaxial/joint.toml) at a chosen mesh size,
through one linear backend: the 3D cohesive rows of benchmarks/README.md, "Plastic 3D tangents".

    .venv/bin/python benchmarks/joint_3d_solvers.py --size 0.002 --backend gmres-amg [--steps 20]

Meshes the cylinder (tetrahedra of ``size`` [m], the joint dipping 55 deg), runs the example with
``steps`` axial steps, and prints one JSON line: dofs, steps, Newton iterations, wall time, peak
memory (this process's), the top's reaction at its extreme and at the end (equal across backends).
Run each backend in its own process so that the peak memory is its own.
"""

from __future__ import annotations

import argparse
import json
import math
import resource
import tempfile
import time
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def main() -> None:
    from rockfrac.case.schema import parse_case
    from rockfrac.mesh.rock_tests import cylinder
    from rockfrac.output.csvout import read_csv
    from rockfrac.runner import run_case

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--size", type=float, required=True, help="element size [m]")
    p.add_argument("--backend", required=True, help="[solver] linear")
    p.add_argument("--steps", type=int, default=20, help="axial steps")
    args = p.parse_args()
    folder = Path(tempfile.mkdtemp())
    msh = cylinder(folder / "cylinder.msh", diameter=0.05, height=0.1, element_size=args.size,
                   joint_dip=math.radians(55))
    d = tomllib.loads((ROOT / "examples" / "rock_tests" / "triaxial" / "joint.toml").read_text())
    d["mesh"]["file"] = str(msh)
    d["stages"][1]["steps"] = args.steps
    d["solver"] = {"linear": args.backend}
    d["output"] = {"picture": False, "vtk": False}
    t0 = time.perf_counter()
    s = run_case(parse_case(d, "joint.toml"), folder / "out")
    wall = time.perf_counter() - t0
    h = read_csv(folder / "out" / "history.csv")
    print(json.dumps({"size": args.size, "backend": args.backend, "dofs": int(s.built.model.n_dofs),
                      "completed": bool(s.result.completed), "steps": len(h["R_top_z"]),
                      "newton_iterations": int(sum(h["newton_iterations"])), "wall_s": round(wall, 1),
                      "peak_gib": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20, 2),
                      "R_top_z_extreme": float(min(h["R_top_z"])), "R_top_z_end": float(h["R_top_z"][-1]),
                      "date": time.strftime("%Y-%m-%d %H:%M")}))


if __name__ == "__main__":
    main()
