"""``rockfrac run``: a case file in, history.csv / points.csv / case.toml / run.log out."""

from __future__ import annotations

import csv
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import tomli_w

from rockfrac.case.build import Built, build, resolve
from rockfrac.case.schema import Case, load_case
from rockfrac.errors import CaseError, RunStopped
from rockfrac.files import prepare_output
from rockfrac.output import checkpoint
from rockfrac.output.csvout import HISTORY_COLUMNS, POINT_COLUMNS, CsvWriter, rows_digest
from rockfrac.solve.linear import make_solver
from rockfrac.solve.newton import NewtonOptions
from rockfrac.solve.stepping import Position, RunResult, SteppingOptions, StepInfo, StopRun, run_stages
from rockfrac.solve.stop import stop_on_signals

STATE_NAMES = {0: "elastic", 1: "plastic"}


@dataclass
class RunSummary:
    """What a run did: the stepping result (final u included), the model it ran, timings."""

    result: RunResult
    out: Path
    wall_time: float
    peak_force: float
    newton_iterations: int
    built: Built | None = None
    warnings: list[str] | None = None
    stop_signal: str | None = None  # the signal that stopped the run early, if one did
    exit_code: int = 0  # what the command line returns for a stopped run (130 SIGINT, 143 SIGTERM)


PENALTY_ACCURACY = 0.01  # rockfrac run warns when an EP penalty's artificial compliance may exceed this


def case_warnings(built: Built) -> list[str]:
    """Things a user should know before trusting the run (not errors: the run goes ahead)."""
    out = []
    from rockfrac.analytic import plane_strain_modulus
    from rockfrac.case.build import mean_cell_size
    from rockfrac.studies.penalty import penalty_rule

    for coh, group in zip(built.case.cohesive_sets, built.cohesives):
        if coh.form.value != "ep":
            continue
        soft_bulk = min(built.case.material_list, key=lambda m: m.E)
        e_plane = plane_strain_modulus(soft_bulk.E, soft_bulk.nu)
        # the bulk's length along the load between surfaces: the specimen for its one crack, a cell
        # for surfaces on many edges
        length = float(np.ptp(built.mesh.nodes[:, 1])) if coh.where.value == "crack" else mean_cell_size(built.mesh)
        k = min(coh.kn, coh.kt)
        need = penalty_rule(e_plane, length, PENALTY_ACCURACY)
        if k < need:
            x = e_plane / (k * length)  # the penalty's compliance relative to the bulk's (upper estimate)
            out.append(f"EP CSE penalty kn, kt = {coh.kn:.3g}, {coh.kt:.3g} Pa/m: k L/E' = {1 / x:.3g} (L = {length:g} m), "
                       f"so the penalty may add up to {100 * x:.3g} % of the bulk's compliance (pre-peak stiffness "
                       f"up to {100 * x / (1 + x):.3g} % too low); k >= {need:.3g} Pa/m keeps the error below "
                       f"{100 * PENALTY_ACCURACY:g} % (rockfrac penalty-study)")
        soft = group.law.softening_modulus()
        if k < soft:
            out.append(f"EP CSE penalty {k:.3g} Pa/m is below the law's softening slope (~{soft:.3g} Pa/m): the "
                       "traction law may have no unique return (the material point snaps back); raise kn, kt or "
                       "use form = 'rp'")
    return out


def point_rows(built: Built, u: np.ndarray) -> dict[str, np.ndarray] | None:
    """Per-point quantities of the discontinuities (CSE node pairs, localized EDE cells), state named,
    concatenated over the surface groups (column set: the cohesive set or the EDE region)."""
    parts = [r for r in (g.point_records(u) for g in built.model.groups) if r is not None]
    if not parts:
        return None
    keys = set.intersection(*(set(p) for p in parts))
    rec = {k: np.concatenate([p[k] for p in parts]) for k in keys}
    rec["point"] = np.arange(rec["x"].shape[0])
    return rec


def history_row(built: Built, info: StepInfo, rec: dict | None) -> dict:
    top = built.top_y_dofs
    reaction = info.f_int[top].sum() / built.thickness  # per unit thickness; no external force on top
    row = {
        "step": info.step,
        "stage": info.stage,
        "load_factor": info.load_factor,
        "u_axial": -float(info.u[top].mean()),
        "F_axial": -float(reaction),
        "newton_iterations": info.newton.iterations,
        "cutbacks": info.cutbacks,
        "control": info.controlled_by,
    }
    if rec is not None and rec["state"].size:
        for k in ("jump_p_norm", "chi", "c", "tan_phi", "tan_psi"):
            if k in rec:
                row[k] = float(np.mean(rec[k]))
        row["n_plastic"] = int(np.sum(rec["state"] == "plastic"))
    elif rec is not None:
        row["n_plastic"] = 0
    if built.embeddeds:
        row["det_ratio"] = min(g.last_event for g in built.embeddeds)
        row["n_localized"] = int(sum(g.localized().size for g in built.embeddeds))
    fractions = [(f, g.wdet.size) for g in built.bulks if (f := g.plastic_fraction()) is not None]
    if fractions:
        row["bulk_plastic"] = sum(f * n for f, n in fractions) / sum(n for _, n in fractions)
    return row


OUTPUTS = ("history.csv", "points.csv", "case.toml", "run.log", checkpoint.FILE, checkpoint.FILE + ".tmp",
           checkpoint.LEGACY, "vtk", "crack_map.png")  # what a run writes into its folder


def _position_arrays(p: Position) -> dict[str, np.ndarray]:
    """A stepping position as plain arrays (for the checkpoint)."""
    return {"stage": np.array(p.stage), "lam": np.array(p.lam), "u": p.u, "count": np.array(p.count),
            "stage_steps": np.array(p.stage_steps), "size_load": np.array(p.size.get("load", np.nan)),
            "size_path": np.array(p.size.get("path", np.nan)), "has_size": np.array(bool(p.size)),
            "forced": np.array(p.forced)}


def _position(a: dict[str, np.ndarray], n_dofs: int, where: Path) -> Position:
    names = ("stage", "lam", "u", "count", "stage_steps", "size_load", "size_path", "has_size", "forced")
    missing = [n for n in names if n not in a]
    if missing or a["u"].shape != (n_dofs,):
        raise CaseError(f"{where}: --resume: the checkpoint was written for a different model "
                        f"({'no ' + missing[0] if missing else 'its displacement vector has another size'})")
    size = {"load": float(a["size_load"]), "path": float(a["size_path"])} if bool(a["has_size"]) else {}
    return Position(int(a["stage"]), float(a["lam"]), a["u"].astype(float), int(a["count"]), int(a["stage_steps"]),
                    size, bool(a["forced"]))


def _resume(out: Path, built: Built, case_text: str) -> tuple[Position, dict]:
    """The position and run counters of the checkpoint in ``out``, with the model's groups restored
    to it, after proving that the checkpoint, history.csv and the case belong together."""
    saved = checkpoint.load(out)  # CaseError if it is not a valid checkpoint
    if saved is None:
        raise CaseError(f"{out}: --resume: no checkpoint here (set [output] checkpoint_every to write them)")
    if saved.case_sha256 != checkpoint.text_sha256(case_text):
        raise CaseError(f"{out}: --resume: the case differs from the one the checkpoint was written for "
                        f"({out / 'case.toml'}); resume with the same case")
    position = _position(saved.position, built.model.n_dofs, out)
    history = out / "history.csv"
    if not history.is_file():
        raise CaseError(f"{history}: --resume: missing, so the checkpoint at step {position.count} cannot be "
                        "matched to its history; rerun with --overwrite")
    try:
        digest = rows_digest(history, position.count)
    except (ValueError, OSError, UnicodeDecodeError, csv.Error) as err:
        raise CaseError(f"{history}: --resume: unreadable ({err}); rerun with --overwrite") from None
    if digest != saved.history_sha256:
        raise CaseError(f"{history}: --resume: not the history of the checkpoint at step {position.count} (its "
                        "rows up to that step differ: the folder mixes two runs); rerun with --overwrite")
    groups = built.model.groups
    if len(saved.groups) != len(groups):
        raise CaseError(f"{out}: --resume: the checkpoint was written for a different model "
                        f"({len(saved.groups)} element groups, this case has {len(groups)})")
    try:
        for g, state in zip(groups, saved.groups):
            g.restore_checkpoint(state)
    except ValueError as err:
        raise CaseError(f"{out}: --resume: {err}") from None
    run = {"F": saved.run.get("F", -np.inf), "iters": int(saved.run.get("iters", 0)),
           "onsets": int(saved.run.get("onsets", 0))}
    return position, run


def _open_log(out: Path, start: Position | None):
    """run.log, line-buffered (a killed run's log is complete up to its last line). A resumed run's
    log is cut after the line of the checkpoint it resumes from, so no step appears twice."""
    path = out / "run.log"
    if start is None:
        return open(path, "w", buffering=1, encoding="utf-8")
    mark = f"  checkpoint at step {start.count}"
    try:
        lines = path.read_text(encoding="utf-8").splitlines()
    except (OSError, UnicodeDecodeError):
        lines = []
    cut = max((i for i, line in enumerate(lines) if line == mark), default=None)
    fh = open(path, "w", buffering=1, encoding="utf-8")
    if cut is None:
        fh.write(f"(run.log of the earlier run did not record its checkpoint at step {start.count}; "
                 "its lines were dropped)\n")
    else:
        fh.write("".join(line + "\n" for line in lines[: cut + 1]))
    return fh


def run_case(case: Case | str | Path, out: str | Path, progress=None, path_label: str | None = None,
             resume: bool = False, overwrite: bool = False, warn=None, on_start=None) -> RunSummary:
    """Run a validated case (or a case file) and write its outputs into ``out``.

    resume: continue from out/checkpoint.npz (written every [output] checkpoint_every steps) with the
    same case, after checking that the checkpoint, history.csv and the case belong together; the
    outputs are cut back to the checkpoint's step and continued, so the result is that of an
    uninterrupted run. A fresh run refuses a folder holding another run's outputs unless
    ``overwrite`` (which deletes them first). on_start(): called once the inputs are checked and the
    folder is ready, before the first step; warn: then called with each warning.
    SIGINT/SIGTERM end the run at the next step boundary (the summary's ``stop_signal`` says which).
    """
    label = path_label or (str(case) if not isinstance(case, Case) else "<case>")
    if not isinstance(case, Case):
        case = load_case(case)
    built = build(case, label)  # every input error surfaces here, before any step
    resolved = resolve(case)
    case_text = tomli_w.dumps(resolved.model_dump(mode="json", exclude_none=True))
    out = prepare_output(out, OUTPUTS, overwrite=overwrite, resume=resume)
    start, run_state = None, {"F": -np.inf, "iters": 0, "onsets": 0}
    if resume:
        start, run_state = _resume(out, built, case_text)
    case_sha = checkpoint.text_sha256(case_text)
    (out / "case.toml").write_text(case_text, encoding="utf-8")
    keep = start.count if start is not None else None
    history = CsvWriter(out / "history.csv", HISTORY_COLUMNS, keep_steps=keep)
    has_points = bool(built.cohesives or built.embeddeds)
    points = CsvWriter(out / "points.csv", POINT_COLUMNS, keep_steps=keep) if case.output.points and has_points \
        else None
    series = None
    if case.output.vtk:
        from rockfrac.output.fields import step_output
        from rockfrac.output.vtk import VtkSeries

        series = VtkSeries(out / "vtk", resume=start is not None)
        if start is not None:
            series.truncate_after(start.count)
    log_fh = _open_log(out, start)

    def log(msg: str) -> None:
        log_fh.write(msg + "\n")

    if start is not None:
        log(f"resumed from the checkpoint at step {start.count}")
    if on_start is not None:
        on_start()
    warnings = case_warnings(built)
    for w in warnings:
        log(f"warning: {w}")
        if warn is not None:
            warn(w)
    sol, opts = case.solver, case.output
    stepping = SteppingOptions(cutback=sol.cutback, min_step=sol.min_step)
    peak = dict(run_state, last=start.count if start is not None else 0)
    stop_frac = case.loading.stop_below_peak_fraction

    def on_step(info: StepInfo) -> None:
        rec = point_rows(built, info.u)
        row = history_row(built, info, rec)
        history.write(row)
        if points is not None:
            rec["step"] = np.full(rec["x"].shape[0], info.step)
            points.write_many(rec, rec["x"].shape[0])
        if series is not None and info.step % opts.vtk_every == 0:
            series.write(info.step, float(info.step), step_output(built, info.u))
        peak["iters"] += info.newton.iterations
        peak["last"] = info.step
        log(f"step {info.step} [{info.stage}] lf={info.load_factor:.6f} u={row['u_axial']:.6e} "
            f"F={row['F_axial']:.6e} iterations={info.newton.iterations}")
        onsets = [o for g in built.embeddeds for o in g.onsets]
        for onset in onsets[peak["onsets"]:]:
            log(f"  bifurcation at step {info.step}: {onset.describe()}")
        peak["onsets"] = len(onsets)
        if progress is not None:
            progress(row)
        if info.stage.startswith("axial"):
            peak["F"] = max(peak["F"], row["F_axial"])
        if opts.checkpoint_every and info.step % opts.checkpoint_every == 0:
            checkpoint.save(out, _position_arrays(info.position), [g.checkpoint_state() for g in built.model.groups],
                            {k: peak[k] for k in ("F", "iters", "onsets")}, case_sha, history.digest())
            log(f"  checkpoint at step {info.step}")
        if info.stage.startswith("axial") and stop_frac is not None and row["F_axial"] < stop_frac * peak["F"]:
            raise StopRun(f"force {row['F_axial']:.1f} N/m fell below {stop_frac} x peak {peak['F']:.1f} N/m")

    t0 = time.perf_counter()
    request = None
    try:
        with stop_on_signals() as request:
            newton = NewtonOptions(sol.max_iterations, sol.tol_residual, sol.tol_energy,
                                   force_scale=1e-6 * max(m.E for m in case.material_list) * case.mesh.width,
                                   should_stop=request)
            result = run_stages(built.model, built.stages, make_solver(sol.linear), newton, stepping, on_step, log,
                                start=start, should_stop=request)
    except KeyboardInterrupt:
        log(f"end: interrupted (repeated SIGINT) after step {peak['last']}; every converged step is kept")
        log_fh.close()
        raise RunStopped(f"interrupted (repeated SIGINT) after step {peak['last']}; every converged step is kept in "
                         f"{out}", 130) from None
    except BaseException:
        log_fh.close()
        raise
    finally:
        history.close()
        if points is not None:
            points.close()
    wall = time.perf_counter() - t0
    if result.stopped:
        log(f"end: stopped by {request.reason} after {result.steps} steps, {wall:.3f} s; every converged step is "
            "kept" + (" (rockfrac run --resume continues from the last checkpoint)" if opts.checkpoint_every else ""))
        log_fh.close()
        return RunSummary(result, out, wall, float(peak["F"]), int(peak["iters"]), built, warnings,
                          stop_signal=request.reason, exit_code=request.exit_code)
    log(f"end: {result.message} after {result.steps} steps, {wall:.3f} s")
    if opts.picture:
        from rockfrac.output.crack_map import save_crack_map
        from rockfrac.output.fields import step_output
        from rockfrac.output.plots import magnification

        mag = magnification(built, result.u)
        cracks = save_crack_map(out / "crack_map.png", step_output(built, result.u), mag,
                                title=f"{case.title or 'rockfrac run'}: step {result.steps}, deformed x{mag:g}")
        log(f"crack_map.png: step {result.steps}, {cracks.opening.size} crack segments, deformed x{mag:g}")
    log_fh.close()
    return RunSummary(result, out, wall, float(peak["F"]), int(peak["iters"]), built, warnings)

