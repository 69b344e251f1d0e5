"""Akantu side of the peer benchmark: intrinsic cohesive_bilinear elements on the block's crack line.

Run with the Akantu virtualenv's Python: ``peer_akantu.py MESH.msh N``; prints one JSON line
(set-up and loading times, Newton iterations, the top force per step). Static Newton-Raphson
with the consistent tangent, the linear solver Akantu's wheel links (Eigen SparseLU, COLAMD
ordering; no MUMPS in the PyPI wheel). Cohesive elements are inserted before the model is
initialized, on the mesh's physical curve "crack" (``cohesive_surfaces``); Akantu's default
selector gives the triangles the first material (elastic) and the cohesive elements the second.
"""

from __future__ import annotations

import json
import os
import resource
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
import peer_problem as P  # noqa: E402

MATERIAL = """
model solid_mechanics_model_cohesive [
  cohesive_inserter [
    cohesive_surfaces = [crack]
  ]
  material elastic [
    name = bulk
    rho = 1.0
    E = {E!r}
    nu = {nu!r}
    Plane_Stress = false
  ]
  material cohesive_bilinear [
    name = crack
    sigma_c = {sigma_c!r}
    G_c = {G_c!r}
    delta_0 = {delta_0!r}
    beta = 1.0
    kappa = 1.0
    penalty = {penalty!r}
  ]
]
"""


def run(mesh_file: str, n: int) -> dict:
    """Set up and load the block in Akantu; times, iterations and top forces [N/m]."""
    import akantu as aka

    t0 = time.perf_counter()
    with tempfile.NamedTemporaryFile("w", suffix=".dat", delete=False) as fh:
        # kt = (beta^2 / kappa) kn = kn; penalty: contact stiffness in compression (unused here)
        fh.write(MATERIAL.format(E=P.E, nu=P.NU, sigma_c=P.SIGMA_C, G_c=P.G_C,
                                 delta_0=P.delta_0(), penalty=P.KN))
    aka.parseInput(fh.name)
    os.unlink(fh.name)
    mesh = aka.Mesh(2)
    mesh.read(mesh_file)
    t_read = time.perf_counter() - t0
    model = aka.SolidMechanicsModelCohesive(mesh)
    model.initFull(_analysis_method=aka._static, _is_extrinsic=False)
    solver = model.getNonLinearSolver()
    solver.set("max_iterations", 50)
    solver.set("convergence_type", aka.SolveConvergenceCriteria.residual)
    # Akantu's residual test is relative to the step's first residual norm (free dofs)
    solver.set("threshold", P.TOL_RESIDUAL)
    model.applyBC(aka.FixedValue(0.0, aka._y), "bottom")
    model.applyBC(aka.FixedValue(0.0, aka._x), "pins")
    model.applyBC(aka.FixedValue(0.0, aka._y), "top")
    top = np.asarray(mesh.getElementGroup("top").getNodeGroup().getNodes()).ravel()
    disp = model.getDisplacement()
    f_int = model.getInternalForce()
    n_cohesive = int(mesh.getNbElement(type=aka._cohesive_2d_4))
    setup = time.perf_counter() - t0

    forces, iterations, u_top = [], [], []
    t1 = time.perf_counter()
    for u in P.step_displacements():
        disp[top, 1] = u
        model.solveStep()
        iterations.append(int(solver.getInt("nb_iterations")))
        forces.append(-float(np.sum(f_int[top, 1])))  # reaction: minus the internal force
        u_top.append(u)
    loading = time.perf_counter() - t1
    return {"code": "akantu", "version": aka.__version__, "N": n, "dofs": int(2 * mesh.getNbNodes()),
            "cohesive_elements": n_cohesive, "setup_s": setup, "setup_read_s": t_read,
            "loading_s": loading, "steps": len(forces), "newton_iterations": int(sum(iterations)),
            "iterations_per_step": iterations, "u_top": u_top, "force": forces,
            "linear_solver": "Eigen SparseLU (COLAMD), the wheel's only direct solver",
            "peak_rss_gib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20}


if __name__ == "__main__":
    print(json.dumps(run(sys.argv[1], int(sys.argv[2]))))
