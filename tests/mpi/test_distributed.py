"""MPI runs on 2 and 3 ranks (3 oversubscribed on this 2-core machine) against the serial run:
``mpiexec`` launches ``mpi_driver.py`` (a test failing on one rank cannot hang pytest: each launch
has a timeout), rank 0 writes the results, the serial reference is computed here.

Tolerance: the histories agree to 1e-9 relative (the serial and parallel Newton iterations stop on
the same criteria, 1e-8 relative residual; the differences left are the LU's and the sums' order,
measured 1e-12); the number of steps and the control of every step are the same, and so are the
Newton iterations but for round-off at the convergence test: one more or one less in at most 2 %
of the steps.
"""

from __future__ import annotations

import functools
import json
import os
import shutil
import subprocess
import sys
import tempfile
import tomllib
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp

pytest.importorskip("petsc4py")
pytest.importorskip("mpi4py")

from rockfrac.case.build import build  # noqa: E402
from rockfrac.case.schema import parse_case  # noqa: E402
from rockfrac.runner import engine_options  # noqa: E402
from rockfrac.solve.linear import make_solver  # noqa: E402
from rockfrac.solve.newton import NewtonOptions  # noqa: E402
from rockfrac.solve.stepping import run_stages  # noqa: E402
from rockfrac.studies import table1  # noqa: E402

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
sys.path.insert(0, str(HERE.parent))
from conftest import EVERY_EDGE, paper_case, pressed_then_pulled  # noqa: E402

BRAZILIAN = ROOT / "examples" / "rock_tests" / "brazilian"
TRIAXIAL = ROOT / "examples" / "rock_tests" / "triaxial"
TIMEOUT = 600
# Open MPI as root (this machine's CI), 3 ranks on 2 cores
MPI_ENV = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               OMPI_MCA_rmaps_base_oversubscribe="1")


def mpirun(n: int, task: str, case: dict, tmp_path: Path, u: np.ndarray | None = None,
           timeout: float = TIMEOUT) -> dict:
    """Run the driver on n ranks; its results (rank 0's npz)."""
    mpiexec = shutil.which("mpiexec")
    assert mpiexec is not None, "mpiexec is not installed (make test installs openmpi-bin)"
    data = dict(case, u=u.tolist()) if u is not None else case
    case_file = tmp_path / f"{task}_{n}.json"
    case_file.write_text(json.dumps(data))
    out = tmp_path / f"{task}_{n}.npz"
    cmd = [mpiexec, "-n", str(n), sys.executable, str(HERE / "mpi_driver.py"), task, str(case_file), str(out)]
    done = subprocess.run(cmd, env=MPI_ENV, capture_output=True, text=True, timeout=timeout)
    assert done.returncode == 0, f"{' '.join(cmd)} failed:\n{done.stdout[-3000:]}\n{done.stderr[-3000:]}"
    with np.load(out) as f:
        result = {k: f[k] for k in f.files}
    assert int(result["ranks"]) == n
    return result


def case_file(case: dict, path: Path, serial: Path | None = None) -> Path:
    """The case written to ``path`` (TOML), and run on one process into ``serial`` if given."""
    import tomli_w

    from rockfrac.runner import run_case

    path.write_text(tomli_w.dumps(case))
    if serial is not None:
        run_case(parse_case(case, str(path)), serial)
    return path


def rockfrac_on_ranks(n: int, case: Path, out: Path, *extra: str) -> subprocess.CompletedProcess:
    """`mpiexec -n n rockfrac run CASE --out OUT --quiet [extra]` (3 ranks oversubscribed here)."""
    cmd = [shutil.which("mpiexec") or "mpiexec", "-n", str(n), str(Path(sys.executable).parent / "rockfrac"), "run",
           str(case), "--out", str(out), "--quiet", *extra]
    return subprocess.run(cmd, env=MPI_ENV, capture_output=True, text=True, timeout=TIMEOUT)


def serial_history(case: dict, solver: str = "auto") -> dict:
    built = build(parse_case(case, "serial"))
    rows: dict[str, list] = {"lam": [], "iterations": [], "path": [], "u": [], "f_int": []}

    def on_step(info) -> None:
        rows["lam"].append(info.load_factor)
        rows["iterations"].append(info.newton.iterations)
        rows["path"].append(info.controlled_by == "path")
        rows["u"].append(info.u.copy())
        rows["f_int"].append(info.f_int.copy())

    newton, stepping = engine_options(built)
    result = run_stages(built.model, built.stages, make_solver(solver), newton, stepping, on_step,
                        u0=built.program.u0, f0=built.program.f0)
    out = {k: np.array(v) for k, v in rows.items()}
    out["message"] = np.array(result.message)
    out["n_u"] = np.array(built.model.n_u)  # the displacements come first, then any multipliers
    return out


def splitting_case(max_steps: int = 200) -> dict:
    """The Brazilian disc split under path control (the coarse mesh): activation, snap-back, path
    (70 path steps; past them the disc is nearly in two, where round-off moves Newton's counts)."""
    case = tomllib.loads((BRAZILIAN / "splitting.toml").read_text())
    case["mesh"]["file"] = str(BRAZILIAN / "disc_coarse.msh")
    case["stages"][0]["max_steps"] = max_steps
    return case


def joint_case(axial_steps: int = 20) -> dict:
    """examples/rock_tests/triaxial/joint.toml (tet4, an EP joint), its axial stage in axial_steps
    (60 in the example; 20 still take the joint past its activation into sliding)."""
    case = tomllib.loads((TRIAXIAL / "joint.toml").read_text())
    case["mesh"]["file"] = str(TRIAXIAL / case["mesh"]["file"])
    case["stages"][1]["steps"] = axial_steps
    return case


def band_case(tracking: str = "local", max_steps: int = 66, element: str = "quad4") -> dict:
    """An embedded shear band (tests/test_crack_tracking.py) on 12 x 24 quads under path control: the
    cells localize one after the other from the weak seed, each continuing the crack from the tip of
    its neighbour ("local"; "nonlocal": in the direction of the stress averaged around the tip over
    every rank's cells), or each on its own ("none"); max_steps before the run's own end."""
    from test_crack_tracking import H, W
    from test_crack_tracking import band_case as tracked

    mesh = {"kind": "block", "element": element, "width": W, "height": H, "nx": 12, "ny": 24,
            "inclusion": [0.0, 0.0067, 0.0034, 0.0167], **({"thickness": 0.01, "nz": 1} if element == "hex8" else {})}
    case = tracked(mesh, {"tracking": tracking, **({"tracking_length": 0.01} if tracking == "nonlocal" else {})})
    case["loading"]["max_steps"] = max_steps
    return case


PATHS = ROOT / "examples" / "path_following"


def nodal_band_case() -> dict:
    """The band of band_case with nodal cracks (the jump a nodal field, the cut cells' sides apart):
    the enrichment's cuts announced across the ranks, the matrix made again at every cut."""
    case = band_case("local", 80)
    case["embedded"].update(kinematics="nodal", kn=1e10, kt=1e10)
    return case


def nodal_gravity_case() -> dict:
    """A nodal crack given across a block in a stress that grows with depth, balanced by gravity (its
    enrichment's share of the boundary tractions and of the body forces, summed over the ranks' cut
    cells), held, then pushed with gravity doubled."""
    rho, g = 1e5, 5.0
    dp = {"model": "drucker_prager", "E": 1.5e7, "nu": 0.3, "beta": 0.480385, "b": 0.321597, "H": 43802.9,
          "kappa0": 1e8, "density": rho}
    return {"mesh": {"kind": "block", "element": "quad4", "width": 0.04, "height": 0.08, "nx": 6, "ny": 12},
            "materials": [dict(dp, region="bulk")],
            "embedded": {"c_r": 0.0, "phi_p": 0.5236, "phi_r": 0.0, "psi_p": 0.087, "alpha_c": 5e3, "alpha_phi": 5e3,
                         "alpha_psi": 5e3, "kinematics": "nodal", "kn": 1e10, "kt": 1e10, "tracking": "local",
                         "cracks": [{"points": [[0.0, 0.0235], [0.04, 0.0555]], "c_p": 1e4}]},
            "initial": {"gravity": [0.0, -g], "stress": [{"stress": [-8e4, -1e5, -9e4, 1e4],
                                                          "gradient": [0.5 * rho * g, rho * g, 0.5 * rho * g, 0.0]}]},
            "stages": [{"name": "hold", "displacement": {"bottom": {"y": 0.0}, "bottom_left": {"x": 0.0}}},
                       {"name": "push", "steps": 6, "gravity": [0.0, -2 * g], "displacement": {"top": {"y": -5e-4}}}]}


def nodal_tets_case(max_steps: int = 60) -> dict:
    """examples/embedded_3d/band_tets on 8 x 16 x 1 (768 tetrahedra): a nodal band tracked through
    the tetrahedra of both ranks, one plane grown cell by cell from the seed."""
    case = tomllib.loads((ROOT / "examples" / "embedded_3d" / "band_tets.toml").read_text())
    case["mesh"].update(nx=8, ny=16, nz=1)
    case["loading"]["max_steps"] = max_steps
    case["output"] = {"vtk": False, "picture": False}
    return case


def nodal_plane_case() -> dict:
    """A plane given across a box of tetrahedra with nodal cracks (tests/test_nodal_3d.py), confined,
    then sheared along it under path control (the plane's cells cut in the serial order on every rank)."""
    from test_nodal_3d import nodal_plane

    from rockfrac.mesh import rock_tests as rt

    msh = rt.box(Path(tempfile.mkdtemp()) / "box.msh", (0.04, 0.04, 0.08), (4, 1, 8), element="tet4")
    case = nodal_plane(msh)
    case["stages"][1]["max_steps"] = 30
    case["output"] = {"vtk": False, "picture": False}
    return case


def bar_case(control: str) -> dict:
    """The path-following bar of examples/path_following (a crack across its middle, under control =
    'arc_length' or 'energy') with an EP crack (kn = kt = 1e11 Pa/m) on 4 x 16 quads. (Its opening
    control variant is not a test of the ranks: five identical crack points after the peak are a
    bifurcation that round-off decides; the notched beam below is.)"""
    case = tomllib.loads((PATHS / f"bar_{control}.toml").read_text())
    case["cohesive"].update(form="ep", kn=1e11, kt=1e11)
    case["mesh"].update(nx=4, ny=16)
    case["stages"][0]["max_steps"] = 150
    return case


def rp_bar_case(control: str) -> dict:
    """examples/path_following's bar with its own rigid-plastic crack (5 points, augmented multipliers
    numbered over every rank's points) on 4 x 16 quads."""
    case = tomllib.loads((PATHS / f"bar_{control}.toml").read_text())
    case["mesh"].update(nx=4, ny=16)
    case["stages"][0]["max_steps"] = 150
    return case


def cmod_case(max_steps: int = 80) -> dict:
    """The notched beam in three-point bending under CMOD control (opening control, bilinear EP
    surfaces on the ligament): past its peak within max_steps."""
    folder = ROOT / "examples" / "rock_tests" / "bending"
    case = tomllib.loads((folder / "notched_beam_cmod.toml").read_text())
    case["mesh"]["file"] = str(folder / case["mesh"]["file"])
    case["stages"][0]["max_steps"] = max_steps
    return case


def breakout_case() -> dict:
    """The borehole breakout (examples/rock_tests/borehole): an in-situ stress at t = 0 ([initial]),
    its traction on the hole released in 40 steps (in_situ), EP surfaces on every edge of the ring."""
    folder = ROOT / "examples" / "rock_tests" / "borehole"
    case = tomllib.loads((folder / "breakout.toml").read_text())
    case["mesh"]["file"] = str(folder / case["mesh"]["file"])
    return case


def gravity_case() -> dict:
    """A block of triangles with EP surfaces on every edge under gravity and an in-situ stress growing
    with depth that balances it at t = 0 (the surfaces carry its tractions), then pushed on its top
    with gravity doubled (a stage's gravity), below the surfaces' strength: the initial state's forces
    and states, not yielding, are what differ on several ranks."""
    rho, g, nu = 2500.0, 9.81, 0.25
    law = {"GfI": 1e4, "GfII": 1e4, "chi_p": 1e6, "chi_r": 0.0, "c_p": 2e6, "c_r": 0.0, "phi_p": 0.5,
           "phi_r": 0.0, "psi_p": 0.0, "alpha_chi": 2e3, "alpha_c": 2e3, "alpha_phi": 9e2, "alpha_psi": 9e2}
    grad = [0.5 * rho * g, rho * g, nu / (1 - nu) * rho * g, 0.0]
    supports = {"bottom": {"y": 0.0}, "left": {"x": 0.0}}
    return {"mesh": {"kind": "block", "element": "tri3", "width": 1.0, "height": 2.0, "nx": 4, "ny": 8},
            "bulk": {"E": 1e9, "nu": nu, "density": rho},
            "cohesive": dict(law, form="ep", where="all", kn=1e11, kt=1e11),
            "initial": {"gravity": [0.0, -g], "stress": [{"stress": [0.0, 0.0, 0.0, 0.0], "gradient": grad,
                                                            "datum": 2.0}]},
            "stages": [{"name": "hold", "steps": 2, "displacement": supports},
                       {"name": "push", "steps": 3, "pressure": {"top": 2e5}, "gravity": [0.0, -2 * g]}]}


def grains_case() -> dict:
    """examples/grains (EP surfaces on the grain boundaries), its first 0.3 mm in 6 steps: the set's
    first activations, on the points of several ranks."""
    case = tomllib.loads((ROOT / "examples" / "grains" / "grains.toml").read_text())
    case["loading"].update(axial_displacement=0.3e-3, axial_steps=6)
    case["output"] = {"picture": False, "vtk": False, "points": False}
    return case


def joint_2d_case(max_steps: int = 30) -> dict:
    """examples/joint: a joint given in advance ([[embedded.cracks]]) across 20 x 40 EDE quads, through
    mesh nodes (moved off them by the cut), sliding at its closed form."""
    case = tomllib.loads((ROOT / "examples" / "joint" / "joint.toml").read_text())
    case["loading"]["axial_steps"] = max_steps
    case["loading"]["axial_displacement"] *= max_steps / 40
    return case


@functools.cache
def _inclusion_msh() -> Path:
    """tests/test_smoothed_normals.py's turned inclusion, meshed once per process."""
    from test_smoothed_normals import inclusion_msh

    return inclusion_msh(Path(tempfile.mkdtemp(prefix="rockfrac_inclusion_")) / "inclusion.msh")


def inclusion_case(form: str = "ep") -> dict:
    """EP or RP surfaces on every edge of an annulus and round the inclusion it holds, smoothed normals
    (the set's frames made from the whole mesh, on rank 0): the inclusion turns, sliding at its polygon's
    vertices, on the points of both ranks."""
    from test_smoothed_normals import inclusion_case as turned

    case = turned(_inclusion_msh(), form, "smoothed")
    case["stages"][1]["steps"] = 5
    case["output"] = {"picture": False, "vtk": False, "points": False}
    return case


def on_edges(case: dict, nx: int | None = None, points: str = "edges") -> dict:
    """The case with its cohesive set's points on its edges, or at their corners (the specimen on
    nx x 2 nx quads if given: the paper's crack then crosses nx cells, one edge each)."""
    case["cohesive"]["points"] = points
    if nx is not None:
        case["mesh"].update(nx=nx, ny=2 * nx)
    return case


CASES = {
    # EP surfaces of the paper's law, load control; the activation is located as an event
    "paper_ep": lambda: paper_case("ep", 1e12, axial_steps=30, axial_displacement=0.6e-3),
    # rigid-plastic surfaces: their multipliers in the ranks' blocks, MUMPS's LU through the saddle points
    "paper_rp": lambda: paper_case("rp", axial_steps=60, axial_displacement=1.5e-3),
    "bar_arc_length_rp": lambda: rp_bar_case("arc_length"),
    "inclusion_smoothed_ep": inclusion_case,
    # its RP form: MUMPS's LU of the saddle point of surfaces on every edge, the junctions' circulations
    "inclusion_smoothed_rp": lambda: inclusion_case("rp"),
    # RP surfaces on every edge, their multipliers unknowns: MUMPS's LU of the saddle point with room for
    # pivots off its zero diagonal (it ran out of workspace and stopped at the first step)
    "every_edge_rp": lambda: dict(EVERY_EDGE, cohesive=dict(table1.CSE_LAW, form="rp", where="all"),
                                  output={"picture": False, "vtk": False, "points": False}),
    # one point per edge (rockfrac.elements.cse_facets): each edge's point on its interface cell's rank,
    # the RP multipliers numbered over the ranks' edges; on the paper's crack, and on every edge
    "paper_ep_edges": lambda: on_edges(paper_case("ep", 1e12, axial_steps=30, axial_displacement=0.6e-3), 6),
    "paper_rp_edges": lambda: on_edges(paper_case("rp", axial_steps=60, axial_displacement=1.5e-3), 6),
    "every_edge_rp_edges": lambda: on_edges(dict(EVERY_EDGE, cohesive=dict(table1.CSE_LAW, form="rp", where="all"),
                                                 output={"picture": False, "vtk": False, "points": False})),
    # corner points (rockfrac.elements.cse_corners): each cell's corners and RP multipliers on its rank
    "paper_rp_corners": lambda: on_edges(paper_case("rp", axial_steps=60, axial_displacement=1.5e-3), 6, "corners"),
    "every_edge_rp_corners": lambda: on_edges(dict(EVERY_EDGE, cohesive=dict(table1.CSE_LAW, form="rp", where="all"),
                                                   output={"picture": False, "vtk": False, "points": False}),
                                              points="corners"),
    "joint_ep_corners": lambda: on_edges(joint_case(), points="corners"),  # 3D: a tetrahedral mesh's joint faces
    "splitting_path": splitting_case,
    # embedded cracks: tracked across the ranks' cells (24 cells cut), and untracked
    "band_local": band_case,
    "band_none": lambda: band_case("none", 43),
    "band_nonlocal": lambda: band_case("nonlocal"),
    "joint_2d_cracks": joint_2d_case,
    # nodal embedded cracks: grown across the ranks' cells, given with in-situ stress and gravity, in 3D
    "band_nodal": nodal_band_case,
    "nodal_gravity": nodal_gravity_case,
    "plane_nodal_3d": nodal_plane_case,
    "band_nodal_tets": nodal_tets_case,
    # the band tracked through one layer of hexahedra of a general 3D body (3D crack fronts across ranks,
    # each tip's direction from the stress averaged round it over every rank's cells; local tracking
    # continues the crack the same way, from its own cell's stress)
    "band_3d_nonlocal": lambda: band_case("nonlocal", 60, element="hex8"),
    # the path controls whose measures are dot products over every rank's dofs
    "bar_arc_length": lambda: bar_case("arc_length"),
    "bar_energy": lambda: bar_case("energy"),
    "cmod_opening": cmod_case,
    # surfaces on every grain boundary of examples/grains (gmsh quads, two materials): each activation
    # of the set is located as an event only while no share of the set, on any rank, has yielded
    "grains_ep": grains_case,
    # an initial state: in-situ stress, its release, gravity at t = 0 and in a stage
    "breakout_initial": breakout_case,
    "gravity_initial": gravity_case,
}


def assert_iteration_totals_agree(par: np.ndarray, ser: np.ndarray, what: str = "") -> None:
    """A chatty case's Newton iterations (see CHATTY): their totals within 5 % and one step's budget
    (one step whose active-set history round-off decides may take up to all of it)."""
    budget = NewtonOptions().max_iterations
    assert abs(par.sum() - ser.sum()) <= 0.05 * ser.sum() + budget, f"{what} newton_iterations"


def assert_same_history(par: dict, ser: dict, any_iterations: bool = False, u_rtol: float = 1e-9,
                        circulating: bool = False) -> None:
    """any_iterations: the Newton iterations of a step may differ by more than one, their total by
    at most 5 % and one step's budget (see CHATTY); u_rtol: the unknowns' tolerance, relative to a step's largest;
    circulating: the displacements alone compared (to u_rtol), the load factors and forces to 1e-8,
    the multipliers only through the forces (see CIRCULATING)."""
    assert "error" not in par, str(par.get("error"))
    assert str(par["message"]) == str(ser["message"])
    assert par["lam"].shape == ser["lam"].shape
    off = np.abs(par["iterations"] - ser["iterations"])
    if any_iterations:
        assert_iteration_totals_agree(par["iterations"], ser["iterations"])
    else:
        assert off.max() <= 1 and np.count_nonzero(off) <= 0.02 * off.size, np.flatnonzero(off)
    np.testing.assert_array_equal(par["path"], ser["path"])
    assert np.abs(par["lam"] - ser["lam"]).max() <= (1e-8 if circulating else 1e-9)
    n = int(ser["n_u"]) if circulating else ser["u"].shape[1]
    for key, rtol in (("u", u_rtol), ("f_int", 1e-8 if circulating else 1e-9)):
        a, b = par[key][:, :n], ser[key][:, :n]
        scale = np.maximum(np.abs(b).max(axis=1, keepdims=True), 1e-300)  # a held step: u = 0
        assert (np.abs(a - b) / scale).max() <= rtol, key


# Cases of RP pairs held shut on loops round every node, whose multipliers' circulation only the
# junctions' perturbed-Lagrangian term fixes (JUNCTION_EPS = 1e-8): Newton's tolerance fixes it to
# about tol / JUNCTION_EPS, so the multipliers of two solvers may differ by more than their
# displacements do. The 4 x 6 specimen's every-edge RP, held shut: multipliers 8e-9 apart on 2 ranks
# (the displacements to 1e-23 of the largest, the forces to 4e-15), compared whole to 1e-7. The
# turned inclusion's RP: its junction multipliers are 2e-4 apart (serial PARDISO against MUMPS on 2
# ranks; 7e-3 between serial MUMPS and the ranks'), and the activation located in the turn's first
# step takes this circulation's tractions, so its load factor is 4e-9 apart (serial MUMPS against 2
# ranks); its displacements agree to 1.4e-7 of a step's largest (at that step), its forces to 2.2e-9
# (measured 2026-12-01).
CIRCULATING = {"every_edge_rp": 1e-7}
DISPLACEMENTS = {"inclusion_smoothed_rp": 1e-6}  # compared on the displacements alone (circulating=True)


# Cases whose Newton iterations per step are not a test of the ranks: at the kink of the bilinear
# law a point's trial sits on its switch to round-off, and Newton reaches the same solution (1e-13)
# in 3 or in 7 iterations depending on the last bits of the residual (measured on one process and
# on 2 ranks).
# The RP cases too: a point that switches twice in a step is pinned (held constrained), and round-off
# decides in which iterate its second switch comes, so the counts differ by a few in a few steps
# while every step ends on the same solution.
# The EP bar under arc-length control on 3 ranks (since 2026-11-30 it runs on 2 only, and stays
# here): MUMPS's parallel LU sums its blocks in the order they arrive, so two runs of the same code
# differ from their second or third step (at 1e-17), and the iterations of a step past the peak (35
# or 38) by 2 in some runs: 411, 413 and 415 in all over four runs of the same code (2026-11-28),
# every step on the same solution.
# The RP bar under arc-length control: its serial reference once (CI, 2026-12-01) converged its first
# step in 1 iteration (the residual after its points switched was at round-off, below ROUNDOFF x the
# tolerance) where every other run, serial or on 2 ranks, took 2; from that start its third step's
# pinned point cycled for 19 iterations instead of 2, and the run took 159 in all against the ranks'
# 140, every step on the same solution (1e-9). So the totals may also differ by one step's budget.
# The RP edge points (the paper's crack, every edge held shut) converge some of their held steps in 1
# iteration, others in 2, by the same round-off test, on one process and on 2 ranks alike; so do the
# RP corner points (171 iterations on one process, 170 on 2 ranks, 171 on 3).
CHATTY = {"cmod_opening", "paper_rp", "paper_rp_edges", "paper_rp_corners", "every_edge_rp_edges", "bar_arc_length_rp", "bar_arc_length", "inclusion_smoothed_rp"}


# on 2 ranks only: the heaviest, and those whose 3 ranks repeat others' (cohesive surfaces and path
# control on 3 ranks: the paper's cases and the disc's splitting, whose path measure is the same sum
# over the ranks' dofs as the bars'; untracked cells and the local tracking: the band tracked from the
# stress averaged over every rank's cells; a given crack: the given nodal crack under gravity; the
# grown nodal band: its enrichment's cuts announced across 2 ranks and its 3-rank launch of the
# CLI below). Three oversubscribed ranks take 7-8 s beyond their start on a bar that one process runs
# in 0.7 s, 8 s on the locally tracked band, 16 s on the nodal one (measured 2026-11-30).
# The joint's EP corner points: 3D corners on 2 ranks (their 2D RP cases run on 3).
SLOW = {"joint_ep_corners", "breakout_initial", "band_3d_nonlocal", "band_nodal_tets", "plane_nodal_3d", "grains_ep", "cmod_opening",
        "bar_arc_length", "bar_energy", "bar_arc_length_rp", "band_none", "band_local", "joint_2d_cracks",
        "band_nodal", "inclusion_smoothed_ep", "inclusion_smoothed_rp"}


def plastic_cylinder_case() -> dict:
    """The Drucker-Prager triaxial cylinder of examples/rock_tests/triaxial (tet4, yielding)."""
    case = tomllib.loads((TRIAXIAL / "drucker_prager.toml").read_text())
    case["mesh"]["file"] = str(TRIAXIAL / case["mesh"]["file"])
    return case


def nodal_band_60_case() -> dict:
    """The nodal band of CASES over its first 60 steps."""
    case = nodal_band_case()
    case["loading"]["max_steps"] = 60
    return case


# every serial history a test compares with: CASES, and the cases of the solver tests below
REFERENCES = {**CASES, "cylinder": plastic_cylinder_case, "joint": joint_case, "band_nodal_60": nodal_band_60_case}


# Cases whose serial reference is solved by MUMPS, as the ranks' are: the turned inclusion's RP saddle
# points, whose PARDISO solves leave relative residuals of 5e-11 to 3e-10 (perturbed pivots), so that
# most of its steps take one more Newton iteration on one process (33 in all against 24 on 2 ranks;
# 23 with MUMPS on one)
SERIAL_SOLVER = {"inclusion_smoothed_rp": "petsc"}


def reference_history(name: str) -> dict:
    return serial_history(REFERENCES[name](), SERIAL_SOLVER.get(name, "auto"))


@functools.cache
def references() -> dict[str, dict]:
    """The serial history of every case of REFERENCES, computed once for every test that compares
    with it, on two processes at once (spawned; the heaviest first): each is one process's work, and
    while they run no rank does."""
    from concurrent.futures import ProcessPoolExecutor
    from multiprocessing import get_context

    heavy = ["band_3d_nonlocal", "breakout_initial", "grains_ep", "joint", "cylinder", "cmod_opening"]
    names = heavy + sorted(set(REFERENCES) - set(heavy))
    with ProcessPoolExecutor(2, mp_context=get_context("spawn")) as pool:
        return dict(zip(names, pool.map(reference_history, names)))


def reference(name: str) -> dict:
    return references()[name]


HISTORIES = {n: [name for name in sorted(CASES) if n == 2 or name not in SLOW] for n in (2, 3)}


@functools.cache
def distributed_histories(n: int) -> dict[str, dict]:
    """The history of every case of HISTORIES[n] on n ranks, all run in one launch: the interpreter,
    PETSc and the compiled kernels are loaded once, not once a case (about 2 s each)."""
    with tempfile.TemporaryDirectory() as folder:
        cases = {name: CASES[name]() for name in HISTORIES[n]}
        got = mpirun(n, "histories", {"cases": cases}, Path(folder), timeout=len(cases) * TIMEOUT / 4)
    return {name: {key.split(".", 1)[1]: value for key, value in got.items() if key.startswith(f"{name}.")}
            for name in HISTORIES[n]}


def test_mumps_out_of_workspace_on_ranks_factorizes_again_with_twice_the_room(tmp_path):
    """The every-edge RP case on 2 ranks with MUMPS's LU started from its default workspace (20 %),
    which its saddle point outgrows: each rank's factor is made again with twice the room until it
    fits (INFOG(1) is global, so every rank agrees), run.log says so once a doubling, and the run
    gives the serial history as with the saddle points' room."""
    name = "every_edge_rp"
    par = mpirun(2, "history_short_room", CASES[name](), tmp_path)
    assert_same_history(par, reference(name), u_rtol=CIRCULATING[name])
    grown = [line for line in str(par["log"]).splitlines() if "ran out of workspace" in line]
    assert grown and "ICNTL(14) = 20 %" in grown[0] and len(grown) == len(set(grown))


@pytest.mark.parametrize("name, n", [(name, n) for n in (2, 3) for name in HISTORIES[n]])
def test_distributed_history_equals_serial(name, n):
    case = CASES[name]()
    ser = reference(name)
    if name == "splitting_path":
        assert ser["path"].sum() >= 60 and ser["lam"][ser["path"]].min() < 0.5 * ser["lam"].max()  # snap-back
    elif name == "joint_2d_cracks":
        assert ser["iterations"].max() == 2  # the joint's surfaces start to slide (then one iteration a step)
    elif name.startswith("band"):
        assert ser["path"].sum() >= 1  # cells localized: path control on their jumps took over
    elif name.startswith("bar"):
        assert ser["path"].sum() >= 20 and ser["lam"][-1] < ser["lam"].max()  # past the peak under control
    elif name.startswith("cmod"):
        assert ser["path"].sum() == ser["path"].size - 1  # every step under CMOD control but the one ending at
        # the first yield (a path step located as a load step)
    elif name.startswith("every_edge_rp"):
        assert ser["iterations"].max() == 2  # held shut: a linear step, its correction and the check
    elif name == "joint_ep_corners":
        assert ser["iterations"].max() == 3  # the joint yields, then slides (two iterations a step)
    elif name == "inclusion_smoothed_ep":
        assert ser["iterations"].max() == 2  # the boundary yields (an elastic step takes one iteration)
    elif name == "inclusion_smoothed_rp":
        assert ser["iterations"].max() >= 3  # points switch between held and sliding
    elif name == "breakout_initial":
        assert ser["iterations"].max() >= 3  # surfaces yield in the run
    elif name == "plane_nodal_3d":
        assert ser["path"].sum() >= 10  # the plane slides under path control
    elif name == "nodal_gravity":
        assert np.abs(ser["u"][0]).max() == 0.0 < np.abs(ser["u"][-1]).max()  # at rest at t = 0, then pushed
    elif name == "gravity_initial":
        assert np.abs(ser["u"][1]).max() == 0.0 < np.abs(ser["u"][-1]).max()  # at rest at t = 0, then pushed
    else:
        assert ser["iterations"].max() >= 4  # the surface yields within the run
    par = distributed_histories(n)[name]
    assert_same_history(par, ser, any_iterations=name in CHATTY,
                        u_rtol=CIRCULATING.get(name, DISPLACEMENTS.get(name, 1e-9)), circulating=name in DISPLACEMENTS)
    # each rank ran on its piece of the mesh: its own cells and, with embedded cracks, the cells
    # sharing a side (nodal cracks: a node) with them
    whole = int(par["whole_cells"][0])
    nodal = case.get("embedded", {}).get("kinematics") == "nodal"
    assert par["piece_cells"].max() <= {2: 0.7, 3: 0.55}[n] * whole + (0.05 * whole if nodal else 0)
    assert par["seen_cells"].max() <= par["piece_cells"].max()


@pytest.mark.parametrize("linear", ["petsc-gamg", "petsc-hypre"])
def test_distributed_amg_on_a_plastic_3d_cylinder(tmp_path, linear):
    """The Drucker-Prager triaxial cylinder (tet4, yielding) on 2 ranks with the AMG-preconditioned
    GMRES (true relative residual 1e-11): the serial direct history to 1e-9."""
    case = plastic_cylinder_case()
    ser = reference("cylinder")
    assert ser["iterations"].max() >= 2  # it yields
    case["solver"] = dict(case.get("solver", {}), linear=linear)
    assert_same_history(mpirun(2, "history", case, tmp_path), ser)


def test_nodal_cracks_with_an_amg_preconditioner_give_the_serial_history(tmp_path, linear="petsc-gamg"):
    """The nodal band on 2 ranks with GMRES and GAMG: the enrichments are the second field of PETSc's
    Schur field split (as RP multipliers are), and the run gives the serial direct history (BoomerAMG
    too, measured: the same split, not repeated here)."""
    case = nodal_band_60_case()
    ser = reference("band_nodal_60")
    assert ser["path"].sum() >= 1  # cells cut: the enrichments are in the system
    case["solver"] = {"linear": linear}
    par = mpirun(2, "history", case, tmp_path)
    assert linear in str(par["solver_line"])
    assert_same_history(par, ser)


@pytest.mark.parametrize("n", [2, 3])
def test_global_matrix_ownership_and_ghosts(tmp_path, n):
    """The 2- and 3-rank tangent, gathered, equals the serial one (plastic surfaces included), every
    cell and cohesive pair is owned by one rank, the ghosts hold their owners' values, and each rank's
    sparsity pattern has the rows of its local dofs only (no pattern in the whole numbering), as its
    vectors have their entries (no vector of the whole model's length); each rank built its model on
    its piece of the mesh, only rank 0 holding the whole."""
    case = splitting_case()
    built = build(parse_case(case, "serial"))
    model = built.model
    model.set_dirichlet(built.stages[0].dirichlet)
    # a smooth field, and the diameter opened past its strength (a third of the way to separation): a
    # softening tangent at its points
    x = built.mesh.nodes
    u = np.zeros(model.n_dofs)
    u[0::2], u[1::2] = 1e-6 * x[:, 1], -2e-6 * x[:, 1]
    for g in built.cohesives:
        for a in range(2):
            u[2 * g.points.plus + a] += 4e-6 * g.points.frame[:, 1, a]  # along the normal n: opening
    model.begin_step()
    asm = model.assemble(u, np.zeros(model.n_dofs), np.zeros(model.n_dofs))  # from the virgin state
    model.commit()
    assert asm.ok and all(g.any_plastic() for g in built.cohesives)
    ref = model.apply_dirichlet(sp.csr_matrix(asm.matrix, copy=True)).toarray()
    par = mpirun(n, "system", case, tmp_path, u)
    assert "error" not in par, str(par.get("error"))
    a = np.zeros_like(ref)
    np.add.at(a, (par["rows"], par["cols"]), par["vals"])
    assert np.abs(a - ref).max() <= 1e-12 * np.abs(ref).max()
    assert np.abs(par["residual"] - asm.residual).max() <= 1e-12 * np.abs(asm.residual).max()
    np.testing.assert_array_equal(np.sort(par["cells"]), np.arange(int(par["n_cells"])))
    pairs = np.concatenate([g.points.minus for g in built.cohesives])
    np.testing.assert_array_equal(np.sort(par["pairs"]), np.sort(pairs))
    assert float(par["ghost_error"]) == 0.0 and par["n_ghosts"].min() > 0
    assert int(par["pattern_not_local"]) == 0  # each rank's pattern: its local dofs' rows only
    assert int(par["vectors_not_local"]) == 0  # and its residual their entries only
    assert par["n_local"].max() < (0.6 if n == 2 else 0.45) * ref.shape[0]  # a share of the whole, and ghosts
    np.testing.assert_array_equal(par["n_global"], [ref.shape[0]] * n)  # the whole model's, on every rank
    # each rank built on its piece of the mesh; only rank 0, which cut the pieces, holds the whole
    share = 0.6 if n == 2 else 0.45
    assert par["piece_cells"].max() < share * int(par["n_cells"]) and par["piece_nodes"].max() < share * int(par["n_nodes"])
    np.testing.assert_array_equal(par["holds_whole"], [True] + [False] * (n - 1))


def test_an_initial_state_out_of_equilibrium_is_refused_on_every_rank(tmp_path):
    """The in-situ stress growing with depth without the gravity that balances it: the serial
    message, raised by every rank (a check that fails on one rank only must not hang the others)."""
    case = gravity_case()
    del case["initial"]["gravity"]
    par = mpirun(3, "history", case, tmp_path)
    assert "not in equilibrium" in str(par["error"]) and "gravity" in str(par["error"])


def test_a_local_solve_across_ranks_is_the_serial_one(tmp_path):
    """rockfrac.solve.elimination on 3 ranks: two displacement dofs owned by two ranks moved (one a
    ghost of the other's piece), the stalled unknowns round them lie on both; their block and residual are the whole
    model's, so the local solve picks the serial unknowns and moves them as one process does."""
    from rockfrac.solve.elimination import eliminate

    case = pressed_then_pulled(8, 16)
    par = mpirun(3, "elimination", case, tmp_path)
    built = build(parse_case(case))
    model = built.model
    model.set_dirichlet(built.stages[0].dirichlet)
    model.begin_step()
    u, zero = par["u_before"], np.zeros(model.n_dofs)
    got = eliminate(model, u, zero, zero, model.assemble(u, zero, zero))
    assert got is not None and np.isin(par["dofs"], got.unknowns).all() and got.unknowns.size <= 32
    assert np.array_equal(par["unknowns"], got.unknowns)
    assert float(par["before"]) == pytest.approx(got.before, rel=1e-12) and got.after <= 1e-3 * got.before
    assert np.abs(par["u_after"] - got.u).max() <= 1e-12 * np.abs(got.u).max()
    held = np.setdiff1d(np.arange(model.n_dofs), got.unknowns)
    assert np.array_equal(par["u_after"][held], u[held])  # every other unknown held


def test_elimination_runs_on_ranks_as_on_one_process(tmp_path):
    """[solver] elimination = true on 2 ranks, by the driver and by `mpiexec rockfrac run` (both refused
    it before): the paper's EP case never stalls, so its history is the serial one."""
    case = paper_case("ep", 1e12, axial_steps=30, axial_displacement=0.6e-3)
    case["solver"] = {"elimination": True}
    par, ser = mpirun(2, "history", case, tmp_path), serial_history(case)
    assert "error" not in par and par["lam"].shape == ser["lam"].shape
    np.testing.assert_array_equal(par["iterations"], ser["iterations"])
    np.testing.assert_allclose(par["u"], ser["u"], rtol=0, atol=1e-10 * np.abs(ser["u"]).max())
    done = rockfrac_on_ranks(2, case_file(case, tmp_path / "elimination.toml"), tmp_path / "out")
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]


def test_auto_on_ranks_takes_gamg_for_large_3d_models_and_hands_over_to_mumps(tmp_path):
    """'auto' on several ranks: MUMPS's LU, except on a 3D model of at least AMG_FROM_3D dofs, where
    it is GMRES + GAMG handing over to MUMPS at its first failure (the serial rule). The jointed
    cylinder (tet4, EP joint at its closed-form activation) on 2 ranks with that choice at its size
    gives the serial history: 3D cohesive surfaces on ranks (MUMPS's LU of 3D models on ranks: the
    embedded bands and planes of CASES)."""
    from rockfrac.parallel.solvers import KrylovGAMG, MumpsLU, distributed_solver
    from rockfrac.solve.fallback import Handover
    from rockfrac.solve.linear import AMG_FROM_3D

    big = distributed_solver("auto", AMG_FROM_3D, 3)
    assert isinstance(big, Handover) and isinstance(big.first, KrylovGAMG) and isinstance(big.then, MumpsLU)
    assert isinstance(distributed_solver("auto", AMG_FROM_3D - 1, 3), MumpsLU)
    assert isinstance(distributed_solver("auto", 100 * AMG_FROM_3D, 2), MumpsLU)
    ser = reference("joint")
    assert ser["iterations"].max() >= 3  # the joint yields within the run
    par = mpirun(2, "history_auto_amg", joint_case(), tmp_path)
    assert "petsc-gamg, then petsc if it fails" in str(par["solver_line"])
    assert_same_history(par, ser)


@pytest.mark.parametrize("linear", ["petsc-gamg", "petsc-hypre"])
def test_rigid_plastic_surfaces_with_an_amg_preconditioner_take_the_schur_field_split(tmp_path, linear):
    """RP multipliers make saddle points: the Krylov solvers precondition by PETSc's Schur field
    split (AMG on the displacements, MUMPS on the multipliers' selfp Schur approximation). The
    paper's RP specimen, on 2 ranks, gives the serial direct history through the crack's slip."""
    case = CASES["paper_rp"]()
    ser = reference("paper_rp")
    assert ser["iterations"].max() >= 3  # the crack yields within the run
    case["solver"] = {"linear": linear}
    assert_same_history(mpirun(2, "history", case, tmp_path), ser, any_iterations=True)


def read_csv(path: Path) -> dict[str, list[str]]:
    import csv

    with path.open() as f:
        rows = list(csv.DictReader(f))
    return {k: [r[k] for r in rows] for k in rows[0]}


def assert_same_table(par: dict, ser: dict, what: str, chatty: bool = False) -> None:
    """Every column alike: text equal, numbers (an empty cell: not applicable) to 1e-9 of their column's
    largest magnitude, or of its family's (reactions, displacements, jumps, tractions: a free node's
    reaction, a node held by symmetry, a jump across the slip are round-off), the energy balance's
    error of the external work; the cohesive points' eps_n_p and eps_s_p (dissipations over G_f, 0 to
    about 1: a point that has not slid holds round-off) of 1. chatty: Newton's iteration counts may
    differ by step, their total by at most 5 % and one step's iteration budget (see CHATTY)."""
    assert list(par) == list(ser) and len(par[next(iter(par))]) == len(ser[next(iter(ser))]), what
    numbers = {}
    for k in ser:
        try:
            numbers[k] = tuple(np.array([float(v) if v != "" else np.nan for v in col]) for col in (par[k], ser[k]))
        except ValueError:
            assert par[k] == ser[k], f"{what} {k}"
    families = ("R_", "u_", "jump", "T_")  # a column's floor: the largest of its family
    floor = {f: max((np.nanmax(np.abs(s), initial=0.0) for k, (_, s) in numbers.items() if k.startswith(f)),
                    default=0.0) for f in families}
    work = np.nanmax(np.abs(numbers["W_external"][1]), initial=0.0) if "W_external" in numbers else 0.0
    if chatty and "newton_iterations" in numbers:
        assert_iteration_totals_agree(*numbers.pop("newton_iterations"), what)
    for k, (p, s) in numbers.items():
        family = max((floor[f] for f in families if k.startswith(f)), default=0.0)
        natural = 1.0 if k in ("eps_n_p", "eps_s_p") else 0.0  # fractions of the fracture energy
        scale = max(np.nanmax(np.abs(s), initial=0.0), family, natural, work if k == "energy_error" else 0.0,
                    1e-300)
        np.testing.assert_array_equal(np.isnan(p), np.isnan(s))
        assert np.nanmax(np.abs(p - s), initial=0.0) <= 1e-9 * scale, f"{what} {k}"


def _flat(mesh) -> tuple[dict[int, np.ndarray], np.ndarray, dict[str, np.ndarray]]:
    """A meshio grid's cells by cell_kind (meshio joins neighbouring blocks of one cell type), the
    kind of every cell, and its cell fields, cell by cell in the file's order."""
    kind = np.concatenate(mesh.cell_data["cell_kind"]).astype(int)
    conn: dict[int, list] = {}
    for block, kinds in zip(mesh.cells, mesh.cell_data["cell_kind"]):
        for k in np.unique(kinds):
            conn.setdefault(int(k), []).append(block.data[kinds == k])
    data = {}
    for name, blocks in mesh.cell_data.items():
        blocks = [b.reshape(b.shape[0], -1).astype(float) for b in blocks]
        data[name] = np.concatenate(blocks)
    return {k: np.vstack(v) for k, v in conn.items()}, kind, data


def assert_pieces_are_the_serial_grid(pvtu: Path, vtu: Path, n: int) -> None:
    """The n VTU pieces a .pvtu joins, put together by their node_id and cell_id fields, are the
    serial run's VTU: the same points (the embedded segments' ends to 1e-12: they follow the normals
    of the stresses at bifurcation), cells (by kind, in the serial order) and fields to 1e-9."""
    import xml.etree.ElementTree as ET

    import meshio

    root = ET.parse(pvtu).getroot()
    sources = [e.get("Source") for e in root.iter("Piece")]
    assert len(sources) == n and all((pvtu.parent / f).exists() for f in sources)
    ser = meshio.read(vtu)
    declared = {e.get("Name") for e in root.find("PUnstructuredGrid/PCellData")}
    assert declared == set(ser.cell_data) | {"cell_id"}
    ser_conn, ser_kind, ser_data = _flat(ser)
    offset = {k: int(np.flatnonzero(ser_kind == k)[0]) for k in ser_conn}  # kinds are in blocks, in order
    points = np.full(ser.points.shape, np.nan)
    point_data = {k: np.full(v.shape, np.nan) for k, v in ser.point_data.items()}
    conn = {k: np.full(c.shape, -1) for k, c in ser_conn.items()}
    data = {k: np.full(v.shape, np.nan) for k, v in ser_data.items()}
    for src in sources:
        piece = meshio.read(pvtu.parent / src)
        ids = piece.point_data["node_id"]
        points[ids] = piece.points
        for k in point_data:
            point_data[k][ids] = piece.point_data[k]
        p_conn, p_kind, p_data = _flat(piece)
        cell_id = p_data["cell_id"][:, 0].astype(int)
        for k, c in p_conn.items():
            conn[k][cell_id[p_kind == k]] = ids[c]
        rows = np.array([offset[k] for k in p_kind]) + cell_id
        for k in data:
            data[k][rows] = p_data[k]
    n_nodes = int(ser_conn[0].max()) + 1  # (cell kind 0: bulk) the mesh nodes, then the segment ends
    np.testing.assert_array_equal(points[:n_nodes], ser.points[:n_nodes])
    assert np.abs(points - ser.points).max() <= 1e-12 * np.abs(ser.points).max()  # ends: from the normals
    for k, want in ser_conn.items():
        np.testing.assert_array_equal(conn[k], want)
    for k, want in ser.point_data.items():
        assert np.abs(point_data[k] - want).max() <= 1e-9 * np.abs(want).max(), k
    for k, want in ser_data.items():
        scale = max(np.nanmax(np.abs(want), initial=0.0), 1e-300)
        np.testing.assert_array_equal(np.isnan(data[k]), np.isnan(want))
        assert np.nanmax(np.abs(data[k] - want), initial=0.0) <= 1e-9 * scale, k


@pytest.fixture(scope="module")
def serial_split(tmp_path_factory) -> tuple[Path, Path]:
    """The disc split under path control with its stop rule and monitor, written as a case file and
    run on one process (once for the rank counts that compare with it): (case file, outputs)."""
    folder = tmp_path_factory.mktemp("split")
    case = splitting_case(2000)
    case["output"] = {"picture": True, "vtk": True, "vtk_every": 48}
    return case_file(case, folder / "split.toml", folder / "serial"), folder / "serial"


@pytest.mark.parametrize("n", [2])
def test_rockfrac_run_on_ranks_writes_the_serial_outputs(tmp_path, n, serial_split):
    """`mpiexec -n N rockfrac run` of the disc split under path control, with its stop rule and
    monitor: history.csv, points.csv (in the serial order) and the crack map as a serial run's. (On
    2 ranks: the disc's split runs on 3 in the histories above, and the command line on 3 in the
    paper's form with monitors below; this launch took 16-17 s on 3 oversubscribed ranks.)"""
    split, serial = serial_split
    done = rockfrac_on_ranks(n, split, tmp_path / "mpi")
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]
    assert done.stderr.count("rockfrac run") == 1  # rank 0 reports, the others are quiet
    for name in ("history.csv", "points.csv"):
        assert_same_table(read_csv(tmp_path / "mpi" / name), read_csv(serial / name), name)
    assert (tmp_path / "mpi" / "crack_map.png").stat().st_size > 10_000
    # the ParaView series: one piece per rank, joined by a .pvtu per step listed in the .pvd
    files = sorted(p.stem for p in (serial / "vtk").glob("*.vtu"))
    steps = len(read_csv(serial / "history.csv")["step"])
    assert len(files) == steps // 48 >= 2 and files == sorted(p.stem for p in (tmp_path / "mpi" / "vtk").glob("*.pvtu"))
    pvd = (tmp_path / "mpi" / "vtk" / "results.pvd").read_text()
    assert all(f"{f}.pvtu" in pvd for f in files) and ".vtu" not in pvd.replace(".pvtu", "")
    for f in files:
        assert_pieces_are_the_serial_grid(tmp_path / "mpi" / "vtk" / f"{f}.pvtu",
                                          serial / "vtk" / f"{f}.vtu", n)
    log = (tmp_path / "mpi" / "run.log").read_text()
    assert f"MPI: {n} ranks" in log and "linear solver: petsc" in log
    # a folder holding a run: rank 0's refusal ends every rank, exit code 2, said once
    again = rockfrac_on_ranks(n, split, tmp_path / "mpi")
    assert again.returncode == 2 and again.stderr.count("holds the outputs of another run") == 1, again.stderr


def test_the_paper_form_with_monitors_on_ranks_writes_the_serial_history(tmp_path):
    """`mpiexec -n 3 rockfrac run` of the paper's EP case ([loading]: u_axial and F_axial over the
    top group) with a point's displacement, the opening between two groups and every group's mean
    displacement and reaction: each rank holds part of each group, the means are the whole groups'
    (history.csv as a serial run's)."""
    case = paper_case("ep", 1e12, axial_steps=20, axial_displacement=0.4e-3)
    case["monitors"] = [{"name": "corner", "kind": "displacement", "at": [0.04, 0.08]},
                        {"name": "bulge", "kind": "opening", "groups": ["left", "right"], "direction": [1.0, 0.0]}]
    case["output"] = {"picture": True}
    paper = case_file(case, tmp_path / "paper.toml", tmp_path / "serial")
    done = rockfrac_on_ranks(3, paper, tmp_path / "mpi")
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]
    par, ser = read_csv(tmp_path / "mpi" / "history.csv"), read_csv(tmp_path / "serial" / "history.csv")
    assert {"u_axial", "F_axial", "corner_x", "bulge", "u_top_y", "R_bottom_y"} <= set(ser)
    assert_same_table(par, ser, "history.csv")
    assert (tmp_path / "mpi" / "crack_map.png").stat().st_size > 10_000


def test_rigid_plastic_surfaces_on_loops_are_counted_on_the_whole_mesh(tmp_path):
    """`mpiexec -n 2 rockfrac run` of the coarse disc with RP surfaces on every edge: the warning on
    the points that lie on loops of pairs round a node counts them on the whole mesh, as one process
    does (rank 0 finds them; a rank's piece cuts the loops)."""
    case = tomllib.loads((ROOT / "examples" / "rock_tests" / "brazilian" / "everywhere.toml").read_text())
    case["mesh"]["file"] = str(ROOT / "examples" / "rock_tests" / "brazilian" / "disc_coarse.msh")
    case["cohesive"].update(form="rp")
    for key in ("kn", "kt"):
        case["cohesive"].pop(key)
    case["stages"][0].update(steps=2, control="load")
    case["stages"][0].pop("max_steps")
    case["output"] = {"picture": False}
    disc = case_file(case, tmp_path / "disc.toml", tmp_path / "serial")
    done = rockfrac_on_ranks(2, disc, tmp_path / "mpi")
    assert done.returncode in (0, 1), done.stdout[-2000:] + done.stderr[-2000:]

    def loops(folder: Path) -> list[str]:
        return [line for line in (folder / "run.log").read_text().splitlines() if "lie on loops" in line]

    serial = loops(tmp_path / "serial")
    assert len(serial) == 1 and "835 of its points" in serial[0], serial  # 888 points, 835 on loops
    assert loops(tmp_path / "mpi") == serial


def test_a_parallel_checkpoint_resumes_bit_for_bit_on_the_same_ranks(tmp_path):
    """2 ranks with a checkpoint every 30 steps, run to its stop rule (143 steps); resumed from the
    last checkpoint (step 120) on 2 ranks: the history is the uninterrupted one to the last bit.
    On 3 ranks the resume is refused, once, by name. With GMRES + GAMG: MUMPS's parallel LU is not
    reproducible to the last bit from one run to the next (its contribution blocks are summed in the
    order they arrive), so neither is a resume through it."""
    case = splitting_case(2000)
    case["output"] = {"picture": False, "checkpoint_every": 30}
    case["solver"] = {"linear": "petsc-gamg"}
    split = case_file(case, tmp_path / "split.toml")
    out = tmp_path / "run"

    def launch(n: int, *extra: str) -> subprocess.CompletedProcess:
        return rockfrac_on_ranks(n, split, out, *extra)

    first = launch(2)
    assert first.returncode == 0, first.stderr[-2000:]
    whole = (out / "history.csv").read_text()
    assert whole.count("\n") == 144 and (out / "checkpoint.rank1.npz").exists()
    refused = launch(3, "--resume")
    assert refused.returncode == 2 and refused.stderr.count("resume on as many") == 1, refused.stderr[-2000:]
    again = launch(2, "--resume")
    assert again.returncode == 0, again.stderr[-2000:]
    assert "resumed from the checkpoint at step 120" in (out / "run.log").read_text()
    assert (out / "history.csv").read_text() == whole


@pytest.mark.parametrize("kinematics", ["elemental", "nodal"])
def test_an_embedded_band_on_ranks_writes_the_serial_outputs_and_resumes(tmp_path, kinematics):
    """`mpiexec -n 2 rockfrac run` of the tracked band: history.csv, points.csv (the cut cells in the
    serial order), the ParaView segments and run.log's onsets as a serial run's; resumed from its
    checkpoint at step 60, the crack-path table (and a nodal crack's enrichment registry) is rebuilt
    from both ranks and the run ends as the uninterrupted one (to 1e-9: MUMPS's parallel LU is not
    bit-reproducible)."""
    import meshio

    case = band_case() if kinematics == "elemental" else nodal_band_case()
    case["output"] = {"points": True, "picture": True, "vtk": True, "vtk_every": 33, "checkpoint_every": 30}
    band = case_file(case, tmp_path / "band.toml", tmp_path / "serial")

    def launch(out: Path, *extra: str) -> None:
        done = rockfrac_on_ranks(2, band, out, *extra)
        assert done.returncode == 1, done.stdout[-2000:] + done.stderr[-2000:]  # 1: ended at max_steps

    launch(tmp_path / "mpi")
    for name in ("history.csv", "points.csv"):
        assert_same_table(read_csv(tmp_path / "mpi" / name), read_csv(tmp_path / "serial" / name), name)
    cut = read_csv(tmp_path / "serial" / "points.csv")["cell"]
    assert len(set(cut)) >= 20  # the band crossed cells of both ranks
    ser_vtu = meshio.read(tmp_path / "serial" / "vtk" / "results_00066.vtu")
    assert "line" in [c.type for c in ser_vtu.cells]  # the band's segments, in pieces of both ranks
    assert_pieces_are_the_serial_grid(tmp_path / "mpi" / "vtk" / "results_00066.pvtu",
                                      tmp_path / "serial" / "vtk" / "results_00066.vtu", 2)

    def onsets(run: str) -> list[str]:
        return sorted(line for line in (tmp_path / run / "run.log").read_text().splitlines() if "bifurcation" in line)

    assert len(onsets("serial")) >= 20 and onsets("mpi") == onsets("serial")
    whole = read_csv(tmp_path / "mpi" / "history.csv")
    launch(tmp_path / "mpi", "--resume")
    assert "resumed from the checkpoint at step 60" in (tmp_path / "mpi" / "run.log").read_text()
    assert_same_table(read_csv(tmp_path / "mpi" / "history.csv"), whole, "resumed history.csv")


def test_3d_embedded_planes_on_ranks_write_the_serial_outputs(tmp_path):
    """`mpiexec -n 2 rockfrac run` of examples/embedded_3d/inclined_joint (a plane given in advance cut
    into the hexahedra of both ranks, sliding to the residual): history.csv and points.csv as the serial
    run's, and the ParaView pieces (the plane's triangles included) the serial grid."""
    import meshio

    case = tomllib.loads((ROOT / "examples" / "embedded_3d" / "inclined_joint.toml").read_text())
    case["mesh"]["file"] = str(ROOT / "examples" / "embedded_3d" / "prism.msh")
    case["stages"][1]["max_steps"] = 60
    case["output"] = {"points": True, "picture": False, "vtk": True, "vtk_every": 30}
    joint = case_file(case, tmp_path / "joint.toml", tmp_path / "serial")
    done = rockfrac_on_ranks(2, joint, tmp_path / "mpi")
    assert done.returncode == 1, done.stdout[-2000:] + done.stderr[-2000:]  # 1: ended at max_steps
    for name in ("history.csv", "points.csv"):
        assert_same_table(read_csv(tmp_path / "mpi" / name), read_csv(tmp_path / "serial" / name), name)
    assert len(set(read_csv(tmp_path / "serial" / "points.csv")["cell"])) == 40
    ser_vtu = meshio.read(tmp_path / "serial" / "vtk" / "results_00060.vtu")
    assert "triangle" in [c.type for c in ser_vtu.cells]
    assert_pieces_are_the_serial_grid(tmp_path / "mpi" / "vtk" / "results_00060.pvtu",
                                      tmp_path / "serial" / "vtk" / "results_00060.vtu", 2)


def test_rigid_plastic_surfaces_on_ranks_write_the_serial_outputs_and_resume(tmp_path):
    """`mpiexec -n 2 rockfrac run` of the RP bar under arc-length control: history.csv and points.csv
    (the multipliers' tractions of both ranks' points) as a serial run's; resumed from its checkpoint,
    the run ends as the uninterrupted one (to 1e-9: MUMPS's parallel LU is not bit-reproducible)."""
    case = rp_bar_case("arc_length")
    case["stages"][0]["max_steps"] = 60
    case["output"] = {"points": True, "picture": False, "checkpoint_every": 25}
    bar = case_file(case, tmp_path / "bar.toml", tmp_path / "serial")

    def launch(*extra: str) -> None:
        done = rockfrac_on_ranks(2, bar, tmp_path / "mpi", *extra)
        assert done.returncode in (0, 1), done.stdout[-2000:] + done.stderr[-2000:]

    launch()
    for name in ("history.csv", "points.csv"):
        assert_same_table(read_csv(tmp_path / "mpi" / name), read_csv(tmp_path / "serial" / name), name, chatty=True)
    pts = read_csv(tmp_path / "serial" / "points.csv")
    assert "plastic" in pts["state"] and len(set(pts["point"])) == 5
    whole = read_csv(tmp_path / "mpi" / "history.csv")
    launch("--resume")
    assert "resumed from the checkpoint at step 50" in (tmp_path / "mpi" / "run.log").read_text()
    assert_same_table(read_csv(tmp_path / "mpi" / "history.csv"), whole, "resumed history.csv", chatty=True)


@pytest.mark.parametrize("form", ["ep", "rp"])
def test_edge_points_on_ranks_write_the_serial_points_csv(tmp_path, form):
    """`mpiexec -n 2 rockfrac run` of the paper's crack with one point per edge: each edge's point on its
    interface cell's rank, written once, in the serial order (points.csv and history.csv as a serial
    run's), the RP multipliers numbered over both ranks' edges."""
    case = CASES[f"paper_{form}_edges"]()
    case["loading"]["axial_steps"] = 20
    case["output"] = {"points": True, "picture": False}
    path = case_file(case, tmp_path / "edges.toml", tmp_path / "serial")
    done = rockfrac_on_ranks(2, path, tmp_path / "mpi")
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]
    for name in ("history.csv", "points.csv"):
        assert_same_table(read_csv(tmp_path / "mpi" / name), read_csv(tmp_path / "serial" / name), name,
                          chatty=form == "rp")
    pts = read_csv(tmp_path / "serial" / "points.csv")
    edges = len(set(pts["point"]))
    assert edges == int(build(parse_case(case, "edges.toml")).cohesives[0].points.n) >= 6
    assert "plastic" in pts["state"]


def test_corner_points_on_ranks_separate_a_specimen_as_one_process_does(tmp_path):
    """`mpiexec -n 2 rockfrac run` of a wide specimen (80 x 20 mm, 8 x 2 quads) whose horizontal crack,
    RP corner points of a bilinear law, is pulled open to full separation: the crack's cells (and their
    multipliers) on both ranks, its middle node pair on an edge of each; history.csv (the fragments and
    the separated length included) and points.csv as a serial run's, two pieces at the end, and the
    dissipation G_c W. (Which rank's points of a shared pair hold: test_corner_points.py.)"""
    from rockfrac.case.build import resolve
    from rockfrac.case.build_mesh import insert_cohesive, make_mesh
    from rockfrac.mesh.partition import partition

    width, gc = 0.08, 100.0
    case = {"mesh": {"kind": "specimen", "width": width, "height": 0.02, "crack": True, "crack_angle": 0.0, "nx": 8,
                     "ny": 1},
            "bulk": {"E": 1e10, "nu": 0.2},
            "cohesive": {"law": "bilinear", "form": "rp", "sigma_c": 1e6, "Gc": gc, "points": "corners",
                         "augmentation": 1e14},
            "stages": [{"name": "pull", "steps": 50, "control": "path", "max_steps": 3000,
                        "displacement": {"bottom": {"x": 0.0, "y": 0.0}, "top": {"x": 0.0, "y": 1e-3}},
                        "stop": {"quantity": "R_top_y", "below_peak_fraction": 1e-6}}],
            "output": {"points": True, "vtk": False, "picture": False}}
    path = case_file(case, tmp_path / "pull.toml", tmp_path / "serial")
    done = rockfrac_on_ranks(2, path, tmp_path / "mpi")
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]
    for name in ("history.csv", "points.csv"):
        assert_same_table(read_csv(tmp_path / "mpi" / name), read_csv(tmp_path / "serial" / name), name)
    h = {k: np.array(v, dtype=float) for k, v in read_csv(tmp_path / "mpi" / "history.csv").items()
         if k in ("n_fragments", "separated", "D_surface_law")}
    assert h["n_fragments"][0] == 1 and h["n_fragments"][-1] == 2
    assert h["separated"][-1] == pytest.approx(width, rel=1e-12)
    assert h["D_surface_law"][-1] == pytest.approx(gc * width, rel=1e-9)
    resolved = resolve(parse_case(case), "pull.toml")
    mesh, cells = insert_cohesive(resolved, make_mesh(resolved, "pull.toml"), "pull.toml")
    ranks = partition(mesh, 2).interface_part[cells[0]]
    assert set(ranks) == {0, 1}  # the crack's cells on both ranks


def test_a_resume_mid_stage_keeps_each_ranks_start_of_a_newly_held_side(tmp_path):
    """A block pressed (stage 1, its right side free to bulge), then its right side held from where it
    is and pulled (stage 2); checkpoints every 5 steps, resumed on 2 ranks from step 10, inside stage
    2: the history is the uninterrupted run's and the serial run's. The stage's start values of the
    right side come from the displacement at the end of stage 1, which each rank holds on its own
    dofs only: a checkpoint keeps every rank's own (one rank's for all put the others' at zero)."""
    split = case_file(pressed_then_pulled(6, 12), tmp_path / "pull.toml", tmp_path / "serial")
    out = tmp_path / "mpi"
    first = rockfrac_on_ranks(2, split, out)
    assert first.returncode == 0, first.stderr[-2000:]
    whole = read_csv(out / "history.csv")
    assert len(whole["step"]) == 12
    assert_same_table(whole, read_csv(tmp_path / "serial" / "history.csv"), "history.csv")
    again = rockfrac_on_ranks(2, split, out, "--resume")
    assert again.returncode == 0, again.stderr[-2000:]
    assert "resumed from the checkpoint at step 10" in (out / "run.log").read_text()
    assert_same_table(read_csv(out / "history.csv"), whole, "resumed history.csv")
    # rank 1's file as if written for another split of the dofs (its checksum made right): refused
    from rockfrac.output import checkpoint

    saved = checkpoint.load(out, checkpoint.rank_file(1))
    assert saved is not None and str(saved.position["local_dofs_sha256"])
    position = {**saved.position, "local_dofs_sha256": np.array("0" * 64)}
    checkpoint.save(out, position, saved.groups, saved.run, saved.case_sha256, "", checkpoint.rank_file(1))
    refused = rockfrac_on_ranks(2, split, out, "--resume")
    assert refused.returncode == 2 and refused.stderr.count("another split of the model") == 1, refused.stderr


def test_a_paraview_piece_and_a_checkpoint_send_no_whole_vector(tmp_path):
    """On 2 ranks, writing a step's ParaView piece and a checkpoint passes each rank's partition
    surface through MPI, not the model: the bytes a rank sends are below a tenth of one whole vector
    (8 bytes a dof; a gathered displacement alone was 8 n_dofs), and the displacement entries it asks
    for are those of its piece's points. A block of 16 x 32 quads with cohesive surfaces on every
    edge (4096 dofs, 1520 interface cells, those on the ranks' border summed across them), pulled."""
    case = {"mesh": {"kind": "block", "element": "quad4", "width": 0.04, "height": 0.08, "nx": 16, "ny": 32},
            "bulk": {"E": 1e10, "nu": 0.2},
            "cohesive": {"law": "bilinear", "form": "ep", "where": "all", "sigma_c": 1e6, "Gc": 100.0, "kn": 1e14,
                         "kt": 1e14},
            "stages": [{"name": "pull", "steps": 2, "displacement": {"bottom": {"y": 0.0}, "bottom_left": {"x": 0.0},
                                                                    "top": {"y": 1e-7}}}]}
    got = mpirun(2, "traffic", case, tmp_path)
    whole = 8 * int(got["n_dofs"])
    assert int(got["n_dofs"]) == 2 * 4 * 16 * 32
    assert int(got["piece_bytes"]) < 0.1 * whole, (int(got["piece_bytes"]), whole)
    assert int(got["checkpoint_bytes"]) < 0.1 * whole, (int(got["checkpoint_bytes"]), whole)
    assert 0 < int(got["asked"]) == 2 * int(got["piece_points"])


def test_nested_multipliers_on_ranks_are_the_serial_ones(tmp_path):
    """[cohesive] multipliers = 'nested' on 2 ranks: the multiplier rows' norm and the Anderson mixing
    of their updates sum over the ranks, so each rank takes the serial iterations. The paper's RP case
    through its activation (the rigid prediction on ranks) and softening, and RP on every edge of a
    block (loops of pairs round the nodes cut by the partition), no multiplier unknowns numbered."""
    every = dict(EVERY_EDGE, cohesive=dict(table1.CSE_LAW, form="rp", where="all", multipliers="nested"))
    paper = paper_case("rp", axial_steps=30, axial_displacement=0.75e-3)  # activation at step 17, then softening
    paper["cohesive"]["multipliers"] = "nested"
    for name, case in (("paper", paper), ("every", every)):
        (tmp_path / name).mkdir()
        par, ser = mpirun(2, "history", case, tmp_path / name), serial_history(case)
        assert "error" not in par and par["lam"].shape == ser["lam"].shape, name
        np.testing.assert_array_equal(par["iterations"], ser["iterations"])
        np.testing.assert_allclose(par["u"], ser["u"], rtol=0, atol=1e-10 * np.abs(ser["u"]).max())
    assert ser["u"].shape[1] == 2 * 4 * 4 * 6  # the every-edge block's displacements, nothing else
