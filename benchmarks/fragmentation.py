"""Fragmentation: a Brazilian disc with cohesive surfaces on every internal edge, EP against RP, two
step sizes, run until the load falls below half its peak (``--stop-fraction``: another fraction).

One command: ``.venv/bin/python benchmarks/fragmentation.py [--specimen disc|grains] [--size S]``
(the disc: about an hour on 2 cores, most of it viscous RP). ``--specimen grains``: the grain-matrix specimen of
:func:`grains_case` in unconfined compression instead (Gmsh quads of 4 mm: about 10,400 internal
edges), table ``fragmentation-grains``. The disc of examples/rock_tests/brazilian (50 mm, loaded over two 10 deg arcs) meshed at
``--size`` (0.9 mm: about 5,100 internal edges), the bilinear law of everywhere.toml on every internal
edge, path control on the mean opening, at 100 and 200 nominal steps. EP (penalty 1e15 Pa/m) runs
with ``[solver] fallback = "implex"`` (IMPL-EX once an implicit step fails at min_step), and again
under load control with the viscous regularisation ``[cohesive] viscosity`` instead (the energy a
snap-back releases goes to D_viscous, reported); RP has no IMPL-EX fallback (its multipliers have no
elastic jump to extrapolate) but runs under load control with the same viscosity too, its
augmentation the EP's penalty (variant "rp viscous"; ``--augmentation R``: another r; ``--penalty K``: the
EP's kn = kt instead of the case's; the viscosity, a Duvaut-Lions relaxation time eta, is then scaled by the
case's kn over R or K, so that eta k, the viscous stress per jump rate, stays the case's EP's). Reports per run: internal edges
(interface points), steps, Newton iterations per step, the step where IMPL-EX took over, wall time,
peak load, the dissipated energy (the work of the forces, and the law's own account), the pieces the
body is in at the end and the length of the surfaces that lost their tensile strength (history.csv's
n_fragments and separated), the platen's displacement at the end against at the peak (below 1: the
run followed a snap-back), and how the run ended. ``--elimination``: the runs with ``[solver] elimination = true`` (their folders and keys marked); ``--normals smoothed``: every set's normals smoothed at its vertices (likewise); ``--points edges`` or ``corners``: every set's points on its edges or at their corners (likewise). Writes ``results/fragmentation.json`` and the ``fragmentation-table`` of README.md.
A run stopped by SIGINT/SIGTERM gets no row (and the runs after it do not start; with no
row added, the table and its json are left as they were). Long runs may span sessions: ``--checkpoint-every N``
saves a checkpoint every N steps and ``--resume`` continues each run from its own (the result is that
of an uninterrupted run; its wall time, the sum of its parts', counts the steps redone since the last
checkpoint; each part is in the run folder's segments.json). The run folders (results/runs) are git-ignored and
do not outlive a session's checkout: ``--bundle`` packs a stopped run's checkpoint, history and segments into
results/resume/<run>.tar.xz, to be committed, and ``--resume`` unpacks it where the folder has no checkpoint.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import sys
import tarfile
import time
import tomllib
from pathlib import Path

import numpy as np

HERE = Path(__file__).parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))
from run import machine, markdown_table, publish  # noqa: E402

VISCOSITY = {"disc": 1e-6, "grains": 1e-5}  # [cohesive] viscosity of the load-controlled EP runs (stage = 1)
REACTION = {"disc": "R_load_top_y", "grains": "R_top_y"}
SIZE = {"disc": 0.0009, "grains": 0.004}
# the grain-matrix specimen's surfaces: the paper's law (Table 1's form) with friction, weaker and more
# brittle than the paper's, strongest inside the grains, weakest on their boundaries
GRAIN_LAW = dict(law="mohr_coulomb", GfI=20.0, GfII=40.0, chi_r=0.0, c_r=0.0, phi_p=0.5236, phi_r=0.3, psi_p=0.05,
                 alpha_chi=200.0, alpha_c=200.0, alpha_phi=50.0, alpha_psi=50.0)


def disc_case(size: float, runs: Path) -> dict:
    """examples/rock_tests/brazilian/everywhere.toml on a disc meshed at ``size``."""
    from rockfrac.mesh.rock_tests import disc

    msh = disc(runs / f"disc_{size:g}.msh", diameter=0.05, contact_angle=math.radians(10.0), element_size=size)
    base = tomllib.loads((ROOT / "examples" / "rock_tests" / "brazilian" / "everywhere.toml").read_text())
    base["mesh"]["file"] = str(msh)
    return base


def grains_case(size: float, runs: Path) -> dict:
    """The grains example's specimen (40 grains in a matrix, 40 x 80 mm, quads of ``size``), both
    materials elastic, EP surfaces on every internal edge: within the grains (3x the matrix's
    strengths), within the matrix, and between them (0.7x); unconfined compression by 1 mm."""
    def section(where: str, regions: list[str], scale: float) -> dict:
        return dict(GRAIN_LAW, form="ep", where=where, regions=regions, chi_p=8000.0 * scale, c_p=6000.0 * scale,
                    kn=2e12, kt=2e12)

    return {"title": "grain-matrix specimen, cohesive surfaces on every internal edge, compressed",
            "mesh": {"kind": "grains", "element": "quad4", "width": 0.04, "height": 0.08, "n_grains": 40,
                     "radius_min": 0.0018, "radius_max": 0.0036, "seed": 0, "element_size": size},
            "materials": [{"region": "grains", "model": "elastic", "E": 6e7, "nu": 0.2},
                          {"region": "matrix", "model": "elastic", "E": 1.5e7, "nu": 0.3}],
            "cohesive": [section("within", ["grains"], 3.0), section("within", ["matrix"], 1.0),
                         section("between", ["matrix", "grains"], 0.7)],
            "stages": [{"name": "compress", "steps": 100, "control": "path", "max_steps": 2000,
                        "displacement": {"bottom": {"y": 0.0}, "bottom_left": {"x": 0.0}, "top": {"y": -1e-3}},
                        "stop": {"quantity": "R_top_y", "below_peak_fraction": 0.5}}]}


RESUME = HERE / "results" / "resume"  # bundles of stopped runs (--bundle), committed
# what a bundle holds: all --resume needs; case.toml (the text the checkpoint was written for) lets a
# later rockfrac whose schema has keys added since resume it (rockfrac.case.resolved.same_case)
BUNDLED = ("checkpoint.npz", "history.csv", "segments.json", "case.toml")


def save_bundle(out: Path) -> Path | None:
    """Pack the run folder's checkpoint, history, segments and case into RESUME/<folder>.tar.xz (written to a
    temporary file and moved into place); None if it has no checkpoint."""
    if not (out / BUNDLED[0]).exists():
        return None
    RESUME.mkdir(parents=True, exist_ok=True)
    path = RESUME / f"{out.name}.tar.xz"
    tmp = path.with_name(path.name + ".tmp")
    with tarfile.open(tmp, "w:xz") as tar:
        for name in BUNDLED:
            if (out / name).exists():
                tar.add(out / name, arcname=name)
    os.replace(tmp, path)
    return path


def restore_bundle(out: Path) -> bool:
    """Unpack RESUME/<folder>.tar.xz into a run folder that has no checkpoint: only the BUNDLED files, as
    plain files (tarfile's "data" filter: no links, no paths out of the folder). True if it did."""
    path = RESUME / f"{out.name}.tar.xz"
    if (out / BUNDLED[0]).exists() or not path.exists():
        return False
    out.mkdir(parents=True, exist_ok=True)
    with tarfile.open(path, "r:xz") as tar:
        members = [m for m in tar.getmembers() if m.isfile() and m.name in BUNDLED]
        tar.extractall(out, members=members, filter="data")
    return True


def saved_runs(saved: Path, specimen: str, size: float) -> dict:
    """The rows of an earlier invocation's results for this mesh, by run key (a rerun of some variants
    keeps the others' rows; each run carries its own date and load)."""
    if not saved.exists():
        return {}
    old = json.loads(saved.read_text())
    if old.get("size") != size:
        return {}
    default = 1e-4 if specimen == "disc" else 1e-3  # the rows before the displacement was a choice
    cpu = old.get("machine", {}).get("cpu")  # the rows before each kept its own: the file's machine
    rows = {}
    for v in old.get("runs", {}).values():
        if "variant" in v:
            v.setdefault("displacement_m", default)
            if cpu is not None:
                v.setdefault("cpu", cpu)
            rows[run_key(v)] = v
    return rows


def run_key(rec: dict) -> str:
    """A run's name in the results: variant, nominal steps, displacement and (if not 0.5) the stop's fraction."""
    stop, aug, pen = rec.get("stop_fraction", 0.5), rec.get("augmentation"), rec.get("penalty")
    return (f"{rec['variant']} {rec['nominal_steps']} {rec['displacement_m']:g}" + (f" stop {stop:g}" if stop != 0.5 else "")
            + (f" r {aug:g}" if aug else "") + (f" kn {pen:g}" if pen else "") + (" elim" if rec.get("elimination") else "")
            + (" smoothed" if rec.get("normals") == "smoothed" else "")
            + (" edges" if rec.get("points_per") == "edges" else "")
            + (" corners" if rec.get("points_per") == "corners" else "")
            + (" elastic-moment" if rec.get("moment") == "elastic" else ""))


def solver_label(rec: dict) -> str:
    """The linear solver a run used: PARDISO unchecked before its solves were checked (rows without
    the log's solver lines), checked, or checked and then the backends that took over (in the order
    they did, over the run's segments): PARDISO without matching (in the saddle order), SuperLU."""
    lines = rec.get("solver")
    if lines is None:
        return "PARDISO, unchecked"
    took = [ln.rsplit("; ", 1)[-1] for ln in lines if ln.endswith("solved from then on")]
    if took:
        names = ["PARDISO without matching, saddle order" if t.startswith("pardiso without matching, saddle")
                 else "PARDISO without matching" if t.startswith("pardiso without matching") else "SuperLU"
                 for t in took]
        return "PARDISO, then " + ", then ".join(names)
    return "PARDISO, checked" if lines and lines[0].startswith("pardiso, checked") else lines[0].split(" ([solver]")[0]


def segment(out: Path, wall: float, summary, resumed: bool) -> float:
    """Record a run's segment (its wall time, steps and end) in out/segments.json, a fresh run's
    replacing any earlier ones; returns the run's wall time so far, the sum of its segments' [s]."""
    path = out / "segments.json"
    done = json.loads(path.read_text()) if resumed and path.exists() else []
    done.append({"date": time.strftime("%Y-%m-%d %H:%M"), "wall_s": wall, "steps": int(summary.result.steps),
                 "load_average": os.getloadavg()[0], "stopped_by": summary.stop_signal})
    path.write_text(json.dumps(done, indent=1))
    return sum(seg["wall_s"] for seg in done)


def base_case(args: argparse.Namespace, size: float, runs: Path) -> tuple[dict, float]:
    """The specimen's case before the variant (``args``: specimen, displacement, checkpoint_every) and
    the EP rows' viscosity [pseudo-time]: the same relaxation time per metre of loading."""
    base = disc_case(size, runs) if args.specimen == "disc" else grains_case(size, runs)
    base["output"] = {"vtk": False, "picture": False, "points": False, "checkpoint_every": args.checkpoint_every}
    visc = VISCOSITY[args.specimen]
    if args.displacement is not None:  # a stage is one unit of pseudo-time
        visc *= (1e-4 if args.specimen == "disc" else 1e-3) / args.displacement
    return base, visc


def variant_case(base: dict, args: argparse.Namespace, variant: str, steps: int, visc: float) -> tuple[dict, str, float]:
    """One run's case: ``variant`` ("ep", "rp", "ep viscous", "rp viscous") at ``steps`` nominal steps
    (``args``: specimen, displacement, stop_fraction, augmentation, penalty, elimination); its run
    folder's name; its viscosity eta."""
    form = variant.split()[0]
    d = json.loads(json.dumps(base))
    sections = d["cohesive"] if isinstance(d["cohesive"], list) else [d["cohesive"]]
    stage = d["stages"][0]
    stage["steps"] = steps
    loaded = stage["displacement"]["load_top" if args.specimen == "disc" else "top"]
    if args.displacement is not None:
        loaded["y"] = -args.displacement
    stage["max_steps"] = 40 * steps
    stage["stop"]["below_peak_fraction"] = args.stop_fraction
    aug = args.augmentation if form == "rp" else None
    pen = args.penalty if form == "ep" else None
    eta = visc
    for coh in sections:
        coh["form"] = form
        kn = coh["kn"]  # the case's EP penalty, whose viscous stress eta kn dJ/dt the rows share
        if pen:
            coh["kn"] = coh["kt"] = pen
        if form == "rp":
            coh.pop("kn")
            coh.pop("kt")
            coh["augmentation"] = aug or kn
        # eta is a relaxation time: the plastic jump rate is the overstress over eta k (k = kn for EP,
        # r for RP), so the overstress of a given flow is eta k dJ/dt. Another k keeps eta k: the
        # viscous stress of the case's EP rows (at a fixed eta, r = 1e15 on the grains' kn = 2e12 was
        # 500 times as viscous and carried 3.5 times the load)
        eta = visc * kn / (pen or aug or kn)
        if variant.endswith("viscous"):  # load control; the overstress ~ eta k dJ/dt stays small
            coh["viscosity"] = eta
    if variant.endswith("viscous"):
        stage["control"] = "load"
        stage.pop("max_steps")
    elif form == "ep":
        d["solver"] = {"fallback": "implex"}
    if args.elimination:
        d.setdefault("solver", {})["elimination"] = True
    if args.normals == "smoothed":
        for coh in sections:
            coh["normals"] = "smoothed"
    if args.points != "nodes":
        for coh in sections:
            coh["points"] = args.points
    name = (f"fragment_{args.specimen}_{variant.replace(' ', '_')}_{steps}" + (f"_r{aug:g}" if aug else "")
            + (f"_kn{pen:g}" if pen else "") + ("_elim" if args.elimination else "")
            + ("_smoothed" if args.normals == "smoothed" else "") + ("" if args.points == "nodes" else f"_{args.points}"))
    return d, name, eta


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--specimen", choices=("disc", "grains"), default="disc")
    ap.add_argument("--size", type=float, default=None, help="element size [m] (disc 0.0009, grains 0.004)")
    ap.add_argument("--variants", nargs="*", default=["ep", "ep viscous", "rp", "rp viscous"],
                    help="the runs to make (none: publish the saved ones' table again)")
    ap.add_argument("--steps", type=int, nargs="+", default=[100, 200])
    ap.add_argument("--displacement", type=float, default=None,
                    help="the loading's displacement [m] (disc 1e-4 at each platen, grains 1e-3 at the top)")
    ap.add_argument("--stop-fraction", type=float, default=0.5,
                    help="stop once the load falls below this fraction of its peak (0.5)")
    ap.add_argument("--augmentation", type=float, default=None,
                    help="RP's augmentation r [Pa/m] (default: the EP's penalty; the grains' friction softens "
                         "faster than it, about 1e14 Pa/m)")
    ap.add_argument("--penalty", type=float, default=None,
                    help="EP's kn = kt [Pa/m] (default: the case's, 1e15 on the disc, 2e12 on the grains)")
    ap.add_argument("--normals", choices=("pairs", "smoothed"), default="pairs",
                    help="[cohesive] normals of every set (smoothed: averaged at a polygonal surface's vertices; the "
                         "run folder's name ends in _smoothed)")
    ap.add_argument("--points", choices=("nodes", "corners", "edges"), default="nodes",
                    help="[cohesive] points of every set (corners: at each edge's ends, RP with one multiplier per "
                         "edge; edges: one per edge, its mean jump and a moment on its rotation; the run folder's "
                         "name ends in _corners or _edges)")
    ap.add_argument("--elimination", action="store_true",
                    help="[solver] elimination = true: a stalled Newton iteration solves its few stalled unknowns "
                         "alone (the run folder's name ends in _elim)")
    ap.add_argument("--checkpoint-every", type=int, default=0,
                    help="save a checkpoint every n converged steps (0: never), for --resume")
    ap.add_argument("--bundle", action="store_true",
                    help="pack a run stopped by SIGINT/SIGTERM into results/resume/<run>.tar.xz (to commit) for a "
                         "later --resume; a run that ends removes its bundle")
    ap.add_argument("--note", default=None,
                    help="a remark on this invocation's runs (e.g. what shared the machine), under the table")
    ap.add_argument("--resume", action="store_true",
                    help="continue each run from the checkpoint in its folder (a run without one starts afresh); "
                         "its wall time is the sum of its segments'")
    args = ap.parse_args()
    from rockfrac.case.schema import parse_case
    from rockfrac.output import checkpoint
    from rockfrac.output.csvout import read_csv
    from rockfrac.runner import run_case

    runs = HERE / "results" / "runs"
    runs.mkdir(parents=True, exist_ok=True)
    size = args.size or SIZE[args.specimen]
    base, visc = base_case(args, size, runs)
    reaction = REACTION[args.specimen]
    name = "fragmentation" if args.specimen == "disc" else "fragmentation_grains"
    if size != SIZE[args.specimen]:  # another mesh: its own results and table (README.md markers)
        name += f"_{1e3 * size:g}mm"
    record: dict = {"machine": machine(), "load_start": os.getloadavg(), "specimen": args.specimen, "size": size,
                    "runs": {}}
    saved = HERE / "results" / f"{name}.json"
    stopped, added = False, {}  # a stop signal; the rows this invocation added
    for variant in args.variants:
        if stopped:
            break
        for steps in args.steps:
            d, folder, eta = variant_case(base, args, variant, steps, visc)
            loaded = d["stages"][0]["displacement"]["load_top" if args.specimen == "disc" else "top"]
            aug = args.augmentation if variant.startswith("rp") else None
            pen = args.penalty if variant.startswith("ep") else None
            out = runs / folder
            if args.resume and restore_bundle(out):
                print(f"{out.name}: unpacked {RESUME / (out.name + '.tar.xz')}", flush=True)
            resume = args.resume and (out / checkpoint.FILE).exists()
            t0 = time.perf_counter()
            s = run_case(parse_case(d), out, overwrite=not resume, resume=resume)
            wall = segment(out, time.perf_counter() - t0, s, resume)
            if s.stop_signal:  # stopped early (SIGINT/SIGTERM): no row (--resume continues it), no more runs
                print(f"{variant} {steps}: stopped by {s.stop_signal} after {s.result.steps} steps; no row"
                      + (" (--resume continues it)" if args.checkpoint_every else ""), flush=True)
                if args.bundle and (packed := save_bundle(out)) is not None:
                    print(f"{variant} {steps}: bundled into {packed} ({packed.stat().st_size / 1e6:.1f} MB)", flush=True)
                stopped = True
                break
            (RESUME / f"{out.name}.tar.xz").unlink(missing_ok=True)  # done: nothing to resume
            h = read_csv(out / "history.csv")
            log = (out / "run.log").read_text()
            r = np.abs(h[reaction])
            its = h["newton_iterations"]
            switched = None
            if "switch to IMPL-EX" in log:
                switched = int(h["step"][np.flatnonzero(np.diff(its == 1))[-1] + 1])
            points = sum(g.points.n for g in s.built.cohesives)
            lam = re.search(r"at load factor ([0-9.]+)", s.result.message)
            below = "half the peak" if args.stop_fraction == 0.5 else f"{args.stop_fraction:g} of the peak"
            ended = (f"below {below}" if "fell below" in s.result.message else
                     f"no convergence at min_step, load factor {lam.group(1)}" if lam else s.result.message[:60])
            viscous = float(h["D_viscous"][-1]) if "D_viscous" in h else 0.0
            split = np.flatnonzero(h["n_fragments"] >= 2)  # the first step with the body in pieces
            pieces = read_csv(out / "fragments.csv") if (out / "fragments.csv").exists() else None
            here = machine()
            rec = {"variant": variant, "nominal_steps": steps, "date": here["date"], "cpu": here["cpu"],
                   "load_average": os.getloadavg()[0], "points": points, "steps": int(s.result.steps), "iterations": int(its.sum()),
                   "iterations_per_step": float(its.mean()), "implex_from_step": switched, "wall_s": wall,
                   "segments": len(json.loads((out / "segments.json").read_text())), "note": args.note,
                   "solver": [ln.split("linear solver: ", 1)[1] for ln in log.splitlines() if "linear solver: " in ln],
                   "peak_N_per_m": float(r.max()), "end_fraction": float(r[-1] / r.max()),
                   "D_dissipated": float(h["D_dissipated"][-1]), "D_surface_law": float(h["D_surface_law"][-1]),
                   "D_viscous": viscous, "energy_error": float(h["energy_error"][-1]), "ended": ended,
                   "viscosity": eta if variant.endswith("viscous") else None,
                   "augmentation": aug, "penalty": pen, "elimination": args.elimination, "normals": args.normals,
                   "points_per": args.points,
                   **({"moment": "capped"} if args.points == "edges" else {}),
                   "displacement_m": -float(loaded["y"]), "stop_fraction": args.stop_fraction, "pieces": int(h["n_fragments"][-1]),
                   "separated_m": float(h["separated"][-1]),
                   "split_step": int(h["step"][split[0]]) if split.size else None,
                   "split_load_fraction": float(r[split[0]] / r.max()) if split.size else None,
                   "largest_pieces": [] if pieces is None else  # area (volume) and centroid of each, largest first
                   [{"size": float(pieces["size"][k]), "x": float(pieces["x"][k]), "y": float(pieces["y"][k])}
                    for k in range(min(3, pieces["size"].shape[0]))],
                   "u_end_over_peak": float(h[reaction.replace("R_", "u_")][-1]
                                            / h[reaction.replace("R_", "u_")][int(np.argmax(r))])}
            added[run_key(rec)] = rec
            print(variant, steps, rec, flush=True)
    if args.variants and not added:  # every run stopped early: the table and its json stay as they were
        return
    # read now, not at the start: an invocation running beside this one may have added its rows since
    record["runs"] = {**saved_runs(saved, args.specimen, size), **added}
    publish_runs(name, record, args.specimen)


def publish_runs(name: str, record: dict, specimen: str) -> None:
    """The table of ``record``'s runs (ordered by variant, displacement, stop and step count) into results/<name>.json
    and README.md."""
    order = {"ep": 0, "ep viscous": 1, "rp": 2, "rp viscous": 3}
    rows, labels = [], []
    ordered = sorted(record["runs"].values(), key=lambda r: (order[r["variant"]], r.get("displacement_m", 0.0),
                                                             -r.get("stop_fraction", 0.5), r["nominal_steps"]))
    for rec in ordered:
        v = rec["variant"]
        eta = rec.get("viscosity") or VISCOSITY[specimen]
        label = v.upper() if not v.endswith("viscous") else f"{v.split()[0].upper()}, viscosity {eta:g}, load control"
        label += f", r = {rec['augmentation']:g} Pa/m" if rec.get("augmentation") else ""
        label += f", kn = {rec['penalty']:g} Pa/m" if rec.get("penalty") else ""
        label += ", elimination" if rec.get("elimination") else ""
        label += ", smoothed normals" if rec.get("normals") == "smoothed" else ""
        label += ", points on edges" if rec.get("points_per") == "edges" else ""
        label += ", points at edge corners" if rec.get("points_per") == "corners" else ""
        label += " (elastic moment)" if rec.get("moment") == "elastic" else ""
        labels.append(f"{label}, {rec['nominal_steps']} steps over {1e3 * rec.get('displacement_m', 1e-4):g} mm")
        rows.append([label,
                     rec["nominal_steps"], f"{1e3 * rec['displacement_m']:g}" if "displacement_m" in rec else "-", rec["points"], rec["steps"], f"{rec['iterations_per_step']:.2f}",
                     rec["implex_from_step"] if rec["implex_from_step"] is not None else "-", f"{rec['wall_s']:.0f}" + (f" ({rec['segments']} parts)" if rec.get("segments", 1) > 1 else ""),
                     f"{rec['peak_N_per_m'] / 1e3:.3g}", f"{rec['end_fraction']:.2f}", f"{rec['D_dissipated']:.4g}",
                     f"{rec['D_surface_law']:.4g}", f"{rec['D_viscous']:.4g}", rec.get("pieces", "-"),
                     f"{1e3 * rec['separated_m']:.1f}" if "separated_m" in rec else "-",
                     f"{rec['u_end_over_peak']:.2f}" if "u_end_over_peak" in rec else "-",
                     f"{rec['split_step']} ({rec['split_load_fraction']:.2f})" if rec.get("split_step") else "-",
                     rec["ended"], solver_label(rec),
                     f"{rec['date']}, {rec['load_average']:.2f}"])
    lines = markdown_table(["form", "nominal steps", "displacement [mm]", "interface points", "steps", "Newton it./step",
                            "IMPL-EX from step", "wall [s]", "peak [kN/m]", "end / peak", "D (work) [J/m]",
                            "D (law) [J/m]", "D (viscous) [J/m]", "pieces", "separated [mm]",
                            "u end / u at peak", "in pieces from step (F / peak)", "ended", "linear solver",
                            "ran (date, load)"],
                           rows)
    notes = [f"{label}: {rec['note']}" for label, rec in zip(labels, ordered) if rec.get("note")]
    publish(name, record, lines, footer=machines_line(record["machine"], labels, ordered)
            + "".join(f" {n}" + ("" if n.endswith(".") else ".") for n in notes))


def machines_line(m: dict, labels: list[str], rows: list[dict]) -> str:
    """The table's footer: the CPU of its rows (each row's own; where they differ, which rows ran on which),
    the cores, and that each row's date and load average are its own run's."""
    cpus = [rec.get("cpu", m["cpu"]) for rec in rows]
    own = "each row's date and load average (at its end) are its own run's."
    if len(set(cpus)) <= 1:
        return f"{cpus[0] if cpus else m['cpu']}, {m['cores']} cores; {own}"
    common = max(dict.fromkeys(cpus), key=cpus.count)  # the most rows' (the first of a tie)
    other = "; ".join(f"{c}: {', '.join(lab for lab, c2 in zip(labels, cpus) if c2 == c)}"
                      for c in dict.fromkeys(cpus) if c != common)
    return f"{m['cores']} cores; {own} {common} for every row but these ({other})."


if __name__ == "__main__":
    main()
