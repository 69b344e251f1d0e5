"""Problem A of ../shared/docs/PEERS.md, side by side: an elastic unit square of N x N quads, one
assembly (sparsity pattern included) and one direct solve, rockfrac against peers in the same run.

One command: ``.venv/bin/python benchmarks/problem_a.py`` (``--sizes 100 300 1000``; ``--repeat K``
runs every code K times per size, interleaved, and keeps the median; ``--quick`` = ``--sizes 100
300 --repeat 1``, prints only). Every code runs in its own fresh process, one after the other, so
each one's peak memory (``ru_maxrss``) is its own:

- **rockfrac**: its own mesh (``cracked_specimen(crack=False)``), ``ElasticSolid`` and ``Model``
  (pattern, slot maps, element values scattered into CSR, Dirichlet bookkeeping), PARDISO through
  ``rockfrac.solve.linear`` with its symmetry detection (``auto``), then once more forced
  unsymmetric (``--unsymmetric`` rows); an untimed N = 8 run first loads its kernels.
- **numpy-pardiso**: the plain vectorized NumPy baseline of PEERS.md (element matrices by einsum,
  COO -> CSR by SciPy, Dirichlet rows and columns by a diagonal mask, PARDISO unsymmetric through
  pypardiso): what a user writes without a FE engine.
- **ngsolve**: NGSolve's own mesh, bilinear form and its sparse Cholesky on the free dofs;
  installed with pip into ``.venv-peers`` on first use (rockfrac's ``.venv`` is never touched).
- **dolfinx**: Debian's python3-dolfinx 0.5 (system Python; ``apt-get install python3-dolfinx``,
  reported as not installed otherwise): its quadrilateral mesh, Q1 vector space, PETSc matrix with
  the boundary conditions, MUMPS LU through a PETSc KSP (preonly); forms compiled by an untimed
  N = 8 run.

Every code reports its top reaction, which must equal E/(1-nu^2) u_top = -16483.516484 N/m (the
field is uniform) to 1e-6; a code that does not is reported as failed. Times: *assembly* =
everything from the mesh to the assembled, constrained matrix (pattern included; for rockfrac also
the Dirichlet set-up), *solve* = factorization + solve, *total* = mesh + assembly + solve.
Writes ``results/problem_a.json`` and the table between the ``problem-a-table`` markers of README.md.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).parent
ROOT = HERE.parent
E, NU, U_TOP = 1.5e7, 0.3, -1e-3
EXACT = E / (1 - NU**2) * U_TOP  # top reaction [N/m]
PEER_VENV = ROOT / ".venv-peers"
PEER_SPEC = ["ngsolve==6.2.2608"]
ROCKFRAC_PY = ROOT / ".venv" / "bin" / "python"


def peak_gib() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20


# ------------------------------------------------------------------------------------------------
# the codes (each runs in its own process: ``problem_a.py --one CODE N``)
# ------------------------------------------------------------------------------------------------


def rockfrac_run(n: int, symmetric: str = "auto") -> dict:
    import numpy as np

    from rockfrac.elements.solid import ElasticSolid
    from rockfrac.fem.reference import QUAD4
    from rockfrac.mesh.specimen import cracked_specimen
    from rockfrac.model import Model
    from rockfrac.solve.linear import Pardiso

    t0 = time.perf_counter()
    mesh = cracked_specimen(1.0, 1.0, crack=False, nx=n, ny=n)
    sets = mesh.node_sets
    t1 = time.perf_counter()
    group = ElasticSolid(mesh.nodes, mesh.cells, QUAD4, E, NU)
    top_y = 2 * sets["top"] + 1
    dirichlet = np.concatenate([2 * sets["bottom"] + 1, 2 * sets["left"], top_y])
    t_pattern = time.perf_counter()
    model = Model(mesh.nodes.shape[0], [group], dirichlet)
    t2 = time.perf_counter()
    u = np.zeros(model.n_dofs)
    u[top_y] = U_TOP
    k = model._const_matrix
    rhs = -(k @ u)
    rhs[model.dirichlet] = 0.0
    a = model.apply_dirichlet(model.pattern.matrix(model._const_data.copy()))
    t3 = time.perf_counter()
    solver = Pardiso()
    solver.symmetric = symmetric
    du = solver.factorize(a).solve(rhs)
    t4 = time.perf_counter()
    u += du
    reaction = float((k @ u)[top_y].sum())
    return {"mesh_s": t1 - t0, "assembly_s": t3 - t1, "of_which_model_s": t2 - t_pattern, "solve_s": t4 - t3,
            "total_s": t4 - t0, "reaction": reaction, "dofs": model.n_dofs, "nnz": model.pattern.nnz,
            "pardiso_mtype": solver.mtype, "peak_gib": peak_gib()}


def numpy_pardiso_run(n: int) -> dict:
    import numpy as np
    import pypardiso
    import scipy.sparse as sp

    t0 = time.perf_counter()
    xs = np.linspace(0.0, 1.0, n + 1)
    x, y = np.meshgrid(xs, xs)
    nodes = np.stack([x.ravel(), y.ravel()], 1)
    ids = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    quads = np.stack([ids[:-1, :-1], ids[:-1, 1:], ids[1:, 1:], ids[1:, :-1]], -1).reshape(-1, 4)
    t1 = time.perf_counter()
    g = 1 / np.sqrt(3.0)
    xi = np.array([[-g, -g], [g, -g], [g, g], [-g, g]])
    c = E / ((1 + NU) * (1 - 2 * NU)) * np.array([[1 - NU, NU, 0], [NU, 1 - NU, 0], [0, 0, (1 - 2 * NU) / 2]])
    sx = np.array([-1.0, 1.0, 1.0, -1.0])
    sy = np.array([-1.0, -1.0, 1.0, 1.0])
    xe = nodes[quads]  # (ne, 4, 2)
    ke = np.zeros((quads.shape[0], 8, 8))
    for q in range(4):
        dn = np.stack([sx * (1 + sy * xi[q, 1]) / 4, sy * (1 + sx * xi[q, 0]) / 4], 1)  # (4, 2) dN/dxi
        jac = np.einsum("ai,eaj->eij", dn, xe)
        det = jac[:, 0, 0] * jac[:, 1, 1] - jac[:, 0, 1] * jac[:, 1, 0]
        inv = np.stack([np.stack([jac[:, 1, 1], -jac[:, 0, 1]], -1), np.stack([-jac[:, 1, 0], jac[:, 0, 0]], -1)],
                       1) / det[:, None, None]
        dx = np.einsum("ai,eij->eaj", dn, inv)  # (ne, 4, 2)
        b = np.zeros((quads.shape[0], 3, 8))
        b[:, 0, 0::2] = dx[:, :, 0]
        b[:, 1, 1::2] = dx[:, :, 1]
        b[:, 2, 0::2] = dx[:, :, 1]
        b[:, 2, 1::2] = dx[:, :, 0]
        ke += np.einsum("e,eki,kl,elj->eij", det, b, c, b)
    dofs = np.stack([2 * quads, 2 * quads + 1], -1).reshape(-1, 8)
    nd = 2 * nodes.shape[0]
    k = sp.coo_matrix((ke.ravel(), (np.repeat(dofs, 8, 1).ravel(), np.tile(dofs, (1, 8)).ravel())),
                      shape=(nd, nd)).tocsr()
    bottom = np.flatnonzero(nodes[:, 1] == 0.0)
    top = np.flatnonzero(nodes[:, 1] == 1.0)
    left = np.flatnonzero(nodes[:, 0] == 0.0)
    fixed = np.unique(np.concatenate([2 * bottom + 1, 2 * left, 2 * top + 1]))
    u = np.zeros(nd)
    u[2 * top + 1] = U_TOP
    rhs = -(k @ u)
    free = np.ones(nd)
    free[fixed] = 0.0
    keep = sp.diags(free)
    a = (keep @ k @ keep + sp.diags(1.0 - free)).tocsr()
    rhs[fixed] = 0.0
    t2 = time.perf_counter()
    solver = pypardiso.PyPardisoSolver(mtype=11)
    du = solver.solve(a, rhs)
    solver.free_memory(everything=True)
    t3 = time.perf_counter()
    u += du
    reaction = float((k @ u)[2 * top + 1].sum())
    return {"mesh_s": t1 - t0, "assembly_s": t2 - t1, "solve_s": t3 - t2, "total_s": t3 - t0,
            "reaction": reaction, "dofs": nd, "nnz": int(a.nnz), "peak_gib": peak_gib()}


def ngsolve_run(n: int) -> dict:
    import ngsolve as ng
    import numpy as np
    from ngsolve.meshes import MakeStructured2DMesh

    t0 = time.perf_counter()
    mesh = MakeStructured2DMesh(quads=True, nx=n, ny=n)  # boundaries bottom, right, top, left
    t1 = time.perf_counter()
    fes = ng.VectorH1(mesh, order=1, dirichletx="left", dirichlety="bottom|top")
    uu, vv = fes.TnT()
    mu, lam = E / (2 * (1 + NU)), E * NU / ((1 + NU) * (1 - 2 * NU))

    def sigma(w):
        eps = ng.Sym(ng.Grad(w))
        return 2 * mu * eps + lam * ng.Trace(eps) * ng.Id(2)

    a = ng.BilinearForm(fes, symmetric=True)
    a += ng.InnerProduct(sigma(uu), ng.Sym(ng.Grad(vv))) * ng.dx
    a.Assemble()
    gfu = ng.GridFunction(fes)
    gfu.Set(ng.CoefficientFunction((0, U_TOP)), definedon=mesh.Boundaries("top"))
    r = gfu.vec.CreateVector()
    r.data = -a.mat * gfu.vec
    t2 = time.perf_counter()
    inv = a.mat.Inverse(fes.FreeDofs(), inverse="sparsecholesky")
    gfu.vec.data += inv * r
    t3 = time.perf_counter()
    f = gfu.vec.CreateVector()
    f.data = a.mat * gfu.vec
    half = fes.ndof // 2  # the x components' dofs, then the y components'
    top = set()
    for el in mesh.Elements(ng.BND):
        if el.mat == "top":
            top.update(d for d in fes.GetDofNrs(el) if d >= half)
    reaction = float(np.asarray(f.FV())[sorted(top)].sum())
    return {"mesh_s": t1 - t0, "assembly_s": t2 - t1, "solve_s": t3 - t2, "total_s": t3 - t0,
            "reaction": reaction, "dofs": fes.ndof, "nnz": int(a.mat.nze), "peak_gib": peak_gib()}


def dolfinx_run(n: int) -> dict:
    import numpy as np
    import ufl
    from dolfinx import fem, mesh
    from dolfinx.fem import petsc as fpetsc
    from mpi4py import MPI
    from petsc4py import PETSc

    t0 = time.perf_counter()
    msh = mesh.create_unit_square(MPI.COMM_WORLD, n, n, mesh.CellType.quadrilateral)
    t1 = time.perf_counter()
    space = fem.VectorFunctionSpace(msh, ("CG", 1))
    uu, vv = ufl.TrialFunction(space), ufl.TestFunction(space)
    mu, lam = E / (2 * (1 + NU)), E * NU / ((1 + NU) * (1 - 2 * NU))

    def sigma(w):
        eps = ufl.sym(ufl.grad(w))
        return 2 * mu * eps + lam * ufl.tr(eps) * ufl.Identity(2)

    a = fem.form(ufl.inner(sigma(uu), ufl.sym(ufl.grad(vv))) * ufl.dx)
    zero = fem.form(ufl.inner(fem.Constant(msh, PETSc.ScalarType((0.0, 0.0))), vv) * ufl.dx)

    def dofs(sub, where):
        return fem.locate_dofs_topological(space.sub(sub), 1, mesh.locate_entities_boundary(msh, 1, where))

    top = dofs(1, lambda x: np.isclose(x[1], 1.0))
    bcs = [fem.dirichletbc(PETSc.ScalarType(0.0), dofs(1, lambda x: np.isclose(x[1], 0.0)), space.sub(1)),
           fem.dirichletbc(PETSc.ScalarType(0.0), dofs(0, lambda x: np.isclose(x[0], 0.0)), space.sub(0)),
           fem.dirichletbc(PETSc.ScalarType(U_TOP), top, space.sub(1))]
    mat = fpetsc.assemble_matrix(a, bcs=bcs)
    mat.assemble()
    b = fpetsc.assemble_vector(zero)
    fpetsc.apply_lifting(b, [a], bcs=[bcs])
    b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    fpetsc.set_bc(b, bcs)
    t2 = time.perf_counter()
    ksp = PETSc.KSP().create(msh.comm)
    ksp.setOperators(mat)
    ksp.setType("preonly")
    ksp.getPC().setType("lu")
    ksp.getPC().setFactorSolverType("mumps")
    uh = fem.Function(space)
    ksp.solve(b, uh.vector)
    uh.x.scatter_forward()
    t3 = time.perf_counter()
    r = fpetsc.assemble_vector(fem.form(ufl.inner(sigma(uh), ufl.sym(ufl.grad(vv))) * ufl.dx))
    reaction = float(r.array[top].sum())
    return {"mesh_s": t1 - t0, "assembly_s": t2 - t1, "solve_s": t3 - t2, "total_s": t3 - t0,
            "reaction": reaction, "dofs": int(uh.x.array.size), "nnz": int(mat.getInfo()["nz_used"]),
            "peak_gib": peak_gib()}


def one(code: str, n: int) -> dict:
    if code.startswith("rockfrac"):
        from rockfrac import threads

        threads.FORCE = "parallel"  # the untimed run loads (or compiles, once) the parallel kernels too
        rockfrac_run(8)  # kernels loaded, MKL loaded: untimed
        threads.FORCE = None
        return rockfrac_run(n, "unsymmetric" if code == "rockfrac-unsymmetric" else "auto")
    if code == "numpy-pardiso":
        return numpy_pardiso_run(n)
    if code == "ngsolve":
        ngsolve_run(8)
        return ngsolve_run(n)
    if code == "dolfinx":
        dolfinx_run(8)  # the forms compiled (FFCx, cached): untimed
        return dolfinx_run(n)
    raise SystemExit(f"unknown code {code}")


# ------------------------------------------------------------------------------------------------
# the driver
# ------------------------------------------------------------------------------------------------


def peer_python() -> Path:
    py = PEER_VENV / "bin" / "python"
    if not py.exists():
        subprocess.run([sys.executable, "-m", "venv", str(PEER_VENV)], check=True)
        subprocess.run([str(py), "-m", "pip", "install", "--quiet", *PEER_SPEC], check=True)
    return py


SYSTEM_PY = Path("/usr/bin/python3")  # Debian's python3-dolfinx (0.5, PETSc 3.18 + MUMPS) lives there
CODES = {"rockfrac": ROCKFRAC_PY, "rockfrac-unsymmetric": ROCKFRAC_PY, "numpy-pardiso": ROCKFRAC_PY,
         "ngsolve": None, "dolfinx": SYSTEM_PY}


def run_one(code: str, n: int) -> dict:
    py = CODES[code] or peer_python()
    load = os.getloadavg()[0]
    if code == "dolfinx" and subprocess.run([str(py), "-c", "import dolfinx"], capture_output=True).returncode:
        return {"code": code, "n": n, "failed": ["not installed (apt-get install python3-dolfinx)"], "load": load}
    proc = subprocess.run([str(py), __file__, "--one", code, str(n)], capture_output=True, text=True)
    if proc.returncode != 0:
        return {"code": code, "n": n, "failed": proc.stderr.strip().splitlines()[-1:] or ["?"], "load": load}
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    out.update(code=code, n=n, load=load)
    if abs(out["reaction"] - EXACT) > 1e-6 * abs(EXACT):
        out["failed"] = [f"top reaction {out['reaction']:.6f} N/m, exact {EXACT:.6f}"]
    return out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--one", nargs=2)
    ap.add_argument("--sizes", type=int, nargs="+", default=[100, 300, 1000])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--codes", nargs="+", default=list(CODES))
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args()
    if args.one:
        print(json.dumps(one(args.one[0], int(args.one[1]))))
        return
    if args.quick:
        args.sizes, args.repeat = [100, 300], 1
    sys.path.insert(0, str(HERE))
    from run import machine, replace_table

    t_start = time.perf_counter()
    rows = []
    for n in args.sizes:
        runs: dict[str, list[dict]] = {c: [] for c in args.codes}
        for _ in range(args.repeat):
            for code in args.codes:  # interleaved: each repetition runs every code once
                r = run_one(code, n)
                runs[code].append(r)
                print(json.dumps(r), flush=True)
        for code, rs in runs.items():
            ok = [r for r in rs if "failed" not in r]
            if not ok:
                rows.append(rs[-1])
                continue
            ok.sort(key=lambda r: r["total_s"])
            med = dict(ok[len(ok) // 2])
            med["runs"] = len(ok)
            med["loads"] = [r["load"] for r in rs]
            rows.append(med)
    info = machine()
    info["load_average"] = os.getloadavg()
    result = {"machine": info, "rows": rows, "wall_s": time.perf_counter() - t_start}
    lines = [f"Machine: {info['cpu']}, {info['cores']} cores; {info['date']}; medians of {args.repeat} interleaved "
             f"runs; load average during the runs {min(min(r.get('loads', [r.get('load', 0)])) for r in rows):.1f}-"
             f"{max(max(r.get('loads', [r.get('load', 0)])) for r in rows):.1f}. Benchmark wall time "
             f"{result['wall_s'] / 60:.1f} min.", "",
             "| N | dofs | code | assembly [s] | solve [s] | total [s] | peak memory [GiB] | total / fastest peer |",
             "|---|---|---|---|---|---|---|---|"]
    for n in args.sizes:
        here = [r for r in rows if r["n"] == n]
        peers = [r["total_s"] for r in here if "failed" not in r and not r["code"].startswith("rockfrac")]
        best = min(peers) if peers else None
        for r in here:
            if "failed" in r:
                lines.append(f"| {n} | - | {r['code']} | failed: {r['failed'][0]} | | | | |")
                continue
            name = r["code"] + (f" (PARDISO mtype {r['pardiso_mtype']})" if "pardiso_mtype" in r else "")
            ratio = f"**{r['total_s'] / best:.2f}**" if best and r["code"].startswith("rockfrac") else ""
            lines.append(f"| {n} | {r['dofs']} | {name} | {r['assembly_s']:.3f} | {r['solve_s']:.3f} | "
                         f"{r['total_s']:.3f} | {r['peak_gib']:.2f} | {ratio} |")
    print("\n".join(lines))
    if not args.quick:
        (HERE / "results").mkdir(exist_ok=True)
        (HERE / "results" / "problem_a.json").write_text(json.dumps(result, indent=1))
        replace_table("problem-a-table", lines)


if __name__ == "__main__":
    main()
