"""``rockfrac run``: a case file in, history.csv / points.csv / case.toml / run.log out."""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import tomli_w

from rockfrac.case.build import Built, build, resolve
from rockfrac.case.schema import Case, load_case
from rockfrac.laws.cohesive_params import MODE_PLASTIC
from rockfrac.output.csvout import HISTORY_COLUMNS, POINT_COLUMNS, CsvWriter
from rockfrac.solve.linear import make_solver
from rockfrac.solve.newton import NewtonOptions
from rockfrac.solve.stepping import RunResult, SteppingOptions, StepInfo, StopRun, run_stages

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


PENALTY_ACCURACY = 0.01  # rockfrac run warns when an EP penalty's artificial compliance may exceed this


def case_warnings(built: Built) -> list[str]:
    """Things a user should know before trusting the run (not errors: the run goes ahead)."""
    out = []
    coh = built.case.cohesive
    if coh is not None and coh.form.value == "ep":
        from rockfrac.analytic import plane_strain_modulus
        from rockfrac.studies.penalty import penalty_rule

        e_plane = plane_strain_modulus(built.case.bulk.E, built.case.bulk.nu)
        length = float(np.ptp(built.mesh.nodes[:, 1]))  # the bulk's length along the load
        k = min(coh.kn, coh.kt)
        need = penalty_rule(e_plane, length, PENALTY_ACCURACY)
        if k < need:
            x = e_plane / (k * length)  # the penalty's compliance relative to the bulk's (upper estimate)
            out.append(f"EP CSE penalty kn, kt = {coh.kn:.3g}, {coh.kt:.3g} Pa/m: k L/E' = {1 / x:.3g} (L = {length:g} m), "
                       f"so the penalty may add up to {100 * x:.3g} % of the bulk's compliance (pre-peak stiffness "
                       f"up to {100 * x / (1 + x):.3g} % too low); k >= {need:.3g} Pa/m keeps the error below "
                       f"{100 * PENALTY_ACCURACY:g} % (rockfrac penalty-study)")
        soft = built.cohesive.law.softening_modulus()
        if k < soft:
            out.append(f"EP CSE penalty {k:.3g} Pa/m is below the law's softening slope (~{soft:.3g} Pa/m): the "
                       "traction law may have no unique return (the material point snaps back); raise kn, kt or "
                       "use form = 'rp'")
    return out


def point_rows(built: Built, u: np.ndarray) -> dict[str, np.ndarray] | None:
    """Per-point quantities of the discontinuity (CSE node pairs or localized EDE cells), state named."""
    if built.embedded is not None:
        rec = built.embedded.records()
        rec["state"] = np.where(rec["mode"] == 1.0, "plastic", "constrained")
        rec["point"] = np.arange(rec["cell"].shape[0])
        return rec
    if built.cohesive is None:
        return None
    rec = built.cohesive.records(u)
    rec["jump_p_norm"] = np.hypot(rec["jump_p_t"], rec["jump_p_n"])
    rigid = built.case.cohesive.form.value == "rp"
    rec["state"] = np.where(rec["mode"] == MODE_PLASTIC, "plastic", "constrained" if rigid else "elastic")
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
    if built.embedded is not None:
        row["det_ratio"] = built.embedded.last_event
        row["n_localized"] = int(built.embedded.localized().size)
    if hasattr(built.bulk, "plastic_fraction"):
        row["bulk_plastic"] = built.bulk.plastic_fraction()
    return row


def run_case(case: Case | str | Path, out: str | Path, progress=None, path_label: str | None = None) -> RunSummary:
    """Run a validated case (or a case file) and write its outputs into ``out``."""
    label = path_label or (str(case) if not isinstance(case, Case) else "<case>")
    if not isinstance(case, Case):
        case = load_case(case)
    built = build(case, label)  # every input error surfaces here, before any step
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    resolved = resolve(case)
    (out / "case.toml").write_text(tomli_w.dumps(resolved.model_dump(mode="json", exclude_none=True)))
    history = CsvWriter(out / "history.csv", HISTORY_COLUMNS)
    has_points = built.cohesive is not None or built.embedded is not None
    points = CsvWriter(out / "points.csv", POINT_COLUMNS) if case.output.points and has_points else None
    log_fh = open(out / "run.log", "w")

    def log(msg: str) -> None:
        log_fh.write(msg + "\n")

    warnings = case_warnings(built)
    for w in warnings:
        log(f"warning: {w}")
    sol = case.solver
    newton = NewtonOptions(sol.max_iterations, sol.tol_residual, sol.tol_energy,
                           force_scale=1e-6 * case.bulk.E * case.mesh.width)
    stepping = SteppingOptions(cutback=sol.cutback, min_step=sol.min_step)
    peak = {"F": -np.inf, "iters": 0, "onsets": 0}
    stop_frac = case.loading.stop_below_peak_fraction

    def on_step(info: StepInfo) -> None:
        rec = point_rows(built, info.u)
        row = history_row(built, info, rec)
        history.write(row)
        if points is not None:
            rec["step"] = np.full(rec["x"].shape[0], info.step)
            points.write_many(rec, rec["x"].shape[0])
        peak["iters"] += info.newton.iterations
        log(f"step {info.step} [{info.stage}] lf={info.load_factor:.6f} u={row['u_axial']:.6e} "
            f"F={row['F_axial']:.6e} iterations={info.newton.iterations}")
        if built.embedded is not None:
            for onset in built.embedded.onsets[peak["onsets"]:]:
                log(f"  bifurcation at step {info.step}: {onset.describe()}")
            peak["onsets"] = len(built.embedded.onsets)
        if progress is not None:
            progress(row)
        if info.stage.startswith("axial"):
            peak["F"] = max(peak["F"], row["F_axial"])
            if stop_frac is not None and row["F_axial"] < stop_frac * peak["F"]:
                raise StopRun(f"force {row['F_axial']:.1f} N/m fell below {stop_frac} x peak {peak['F']:.1f} N/m")

    t0 = time.perf_counter()
    try:
        result = run_stages(built.model, built.stages, make_solver(sol.linear), newton, stepping, on_step, log)
    finally:
        history.close()
        if points is not None:
            points.close()
    wall = time.perf_counter() - t0
    log(f"end: {result.message} after {result.steps} steps, {wall:.3f} s")
    log_fh.close()
    return RunSummary(result, out, wall, float(peak["F"]), int(peak["iters"]), built, warnings)
