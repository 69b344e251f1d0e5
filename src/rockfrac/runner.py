"""``rockfrac run``: a case file in, history.csv / points.csv / fragments.csv / case.toml / run.log out.

The run composes the observers of :mod:`rockfrac.output.observers` around the stepping: the
history (with its generic quantities, :mod:`rockfrac.output.history`), the point records, the
ParaView series, the log, checkpoints, stop rules and progress each see every converged step.
"""

from __future__ import annotations

import csv
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from rockfrac.analytic import penalty_rule, plane_strain_modulus
from rockfrac.case.build import Built, Distribution, build, mean_cell_size
from rockfrac.case.resolved import resolved_text, same_case
from rockfrac.case.schema import Case, load_case
from rockfrac.elements.cse_groups import CohesiveRP
from rockfrac.elements.ede_nodal_parts import HeldEnrichment
from rockfrac.errors import CaseError, RunStopped
from rockfrac.files import prepare_output
from rockfrac.mesh.interfaces import looped_pairs_by_set
from rockfrac.output import checkpoint
from rockfrac.output.csvout import POINT_COLUMNS, POINT_COLUMNS_3D, read_csv, rows_digest
from rockfrac.output.history import History, axial_columns, crack_columns, step_columns
from rockfrac.output.observers import (
    Checkpoints,
    FragmentsCsv,
    HistoryCsv,
    Observer,
    PointsCsv,
    Progress,
    Quiet,
    RunLog,
    Step,
    StopRules,
    VtkSeriesWriter,
    position_from_arrays,
)
from rockfrac.solve.linear import make_solver
from rockfrac.solve.newton import NewtonOptions
from rockfrac.solve.stepping import Position, RunResult, StepInfo, SteppingOptions, run_stages
from rockfrac.solve.stop import stop_on_signals
from rockfrac.values import given

OUTPUTS = ("history.csv", "points.csv", "fragments.csv", "case.toml", "run.log", checkpoint.FILE,
           checkpoint.FILE + ".tmp", checkpoint.LEGACY, "vtk", "crack_map.png")  # what a run writes into its folder
PENALTY_ACCURACY = 0.01  # rockfrac run warns when an EP penalty's artificial compliance may exceed this


@dataclass
class RunSummary:
    """What a run did: the stepping result (final u included), the model it ran, timings."""

    result: RunResult
    out: Path
    wall_time: float
    peak_force: float  # peak F_axial of the [loading] form's axial stages (nan for [[stages]])
    newton_iterations: int
    built: Built | None = None
    warnings: list[str] | None = None
    stop_signal: str | None = None  # the signal that stopped the run early, if one did
    exit_code: int = 0  # what the command line returns for a stopped run (130 SIGINT, 143 SIGTERM)


def case_warnings(built: Built) -> list[str]:
    """Things a user should know before trusting the run (not errors: the run goes ahead)."""
    out = []
    model = built.model
    loops: list[np.ndarray | None] | None = built.loops  # an MPI rank's: found by rank 0 on the whole mesh
    if loops is None and any(isinstance(g, CohesiveRP) for g in built.cohesives):  # the pairs of every set
        loops = list(looped_pairs_by_set([g.points.minus for g in built.cohesives],
                                         [g.points.plus for g in built.cohesives], built.mesh.n_nodes))
    for j, (coh, group) in enumerate(zip(built.case.cohesive_sets, built.cohesives)):
        if isinstance(group, CohesiveRP) and not group.rings:  # a cell's multipliers close no ring of pairs
            continue
        if isinstance(group, CohesiveRP):
            mask = loops[j] if loops is not None else None
            assert mask is not None
            count = model.reduce_sum(int(np.count_nonzero(mask)))
            if count:
                out.append(f"RP CSE {group.name!r}: {count} of its points lie on loops of surfaces round a node (a node "
                           "inside the mesh split on every edge round it). Held by the others, such a rigid-plastic "
                           "surface cannot open alone: a crack forms only where a chain of surfaces has yielded, "
                           "later and at a higher load than with EP surfaces (a path step they hold shut is taken as "
                           "a load step); through the snap-backs of fragmentation use [cohesive] viscosity under load "
                           "control (benchmarks/README.md, 'Fragmentation'). Where a crack meets unyielded pairs at "
                           "such a node, or bends there, a pair can sit on its yield surface with no flow and the "
                           "ring's multipliers are statically indeterminate: Newton's active set may cycle there and "
                           "the steps stall (the small grains stop at 0.28 of their stage where EP runs whole: "
                           "benchmarks/README.md, 'Nested multipliers'); EP surfaces take that mismatch in their "
                           "elastic jumps")
            continue
        soft_bulk = min(built.case.material_list, key=lambda m: m.E)
        e_plane = plane_strain_modulus(soft_bulk.E, soft_bulk.nu)
        # the bulk's length along the load between surfaces: the specimen for its one crack, a cell
        # for surfaces on many edges
        whole = built.whole if built.whole is not None else built.mesh  # the whole mesh's, on the rank that writes
        length = float(np.ptp(whole.nodes[:, 1])) if coh.where.value == "crack" else mean_cell_size(whole)
        kn, kt = given(coh.kn, "kn"), given(coh.kt, "kt")
        which = f" ({group.name})" if len(built.case.cohesive_sets) > 1 else ""  # one line per set: named
        k = min(kn, kt)
        need = penalty_rule(e_plane, length, PENALTY_ACCURACY)
        if k < need:
            x = e_plane / (k * length)  # the penalty's compliance relative to the bulk's (upper estimate)
            out.append(f"EP CSE penalty kn, kt = {kn:.3g}, {kt:.3g} Pa/m: k L/E' = {1 / x:.3g} (L = {length:g} m), "
                       f"so the penalty may add up to {100 * x:.3g} % of the bulk's compliance (pre-peak stiffness "
                       f"up to {100 * x / (1 + x):.3g} % too low); k >= {need:.3g} Pa/m keeps the error below "
                       f"{100 * PENALTY_ACCURACY:g} % (rockfrac penalty-study){which}")
        soft = group.law.softening_modulus()
        if k < soft:
            out.append(f"EP CSE penalty {k:.3g} Pa/m is below the law's softening slope (~{soft:.3g} Pa/m): the "
                       "traction law may have no unique return (the material point snaps back); raise kn, kt or "
                       f"use form = 'rp'{which}")
    return out


def point_rows(built: Built, u: np.ndarray) -> dict[str, np.ndarray] | None:
    """Per-point quantities of the discontinuities (CSE node pairs, localized EDE cells), state named,
    concatenated over the surface groups (column set: the cohesive set or the EDE region)."""
    model = built.model
    parts = [r for g in model.groups if (r := model.gather_records(g.point_records(u), g.record_order())) is not None]
    if not parts:
        return None
    keys = set.intersection(*(set(p) for p in parts))
    rec = {k: np.concatenate([p[k] for p in parts]) for k in keys}
    rec["point"] = np.arange(rec["x"].shape[0])
    return rec


def history_row(built: Built, info: StepInfo, rec: dict | None) -> dict:
    """The step's base, paper and crack columns (what the engine benchmarks record)."""
    row = step_columns(info)
    if built.case.loading is not None:
        row.update(axial_columns(info.u, info.f_int, built.top_y_dofs, built.thickness))
    row.update(crack_columns(built.model.groups, rec))
    return row


def make_history(built: Built, path: str = "<case>") -> History:
    """The history quantities of a built case, its stop rules checked against them."""
    history = History(built.mesh, built.model, thickness=built.thickness, u0=built.program.u0, f0=built.program.f0,
                      monitors=built.monitors, axial_dofs=built.top_y_dofs if built.case.loading is not None else None,
                      axial_count=built.axial_count, whole=built.whole,
                      means=tuple(n for g in built.cohesives for n in g.law.record_names if not n.startswith("eps_")),
                      separated_fraction=built.case.output.separated_fraction)
    for m in history.monitors:
        clash = [c for c in m.columns if c in history.reserved]
        if clash:
            raise CaseError(f"{path}: [[monitors]] name {m.name!r}: its column {clash[0]!r} is already a history "
                            "column; choose another name")
    for k, stop in enumerate(built.program.stops):
        if stop is not None and stop.quantity not in history.columns:
            example = ", ".join(c for c in history.columns if c.startswith("R_"))
            raise CaseError(f"{path}: [stages {k + 1}] stop.quantity: {stop.quantity!r} is not a history column "
                            f"(reactions: {example or 'none'})")
    return history


def _pieces_at(history: Path, step: int | None) -> int:
    """The body's pieces (history.csv's n_fragments) at a resumed run's checkpoint step (1: a new run,
    or a history without the column or without its value: a model without cohesive surfaces)."""
    if step is None:
        return 1
    rows = read_csv(history)
    at = np.flatnonzero(rows["step"] == step)
    value = float(rows["n_fragments"][at[-1]]) if "n_fragments" in rows and at.size else math.nan
    return int(value) if math.isfinite(value) else 1


def _resume(out: Path, built: Built, case_text: str, rank: int = 0) -> tuple[Position, dict]:
    """The position and run counters of the checkpoint in ``out``, with the model's groups restored
    to it, after proving that the checkpoint, history.csv and the case belong together (an MPI run:
    on every rank, the same number of ranks, each from its own file; a refusal on any rank is said
    on all)."""
    try:
        found = _restore(out, built, case_text, rank)
        failure = None
    except CaseError as err:
        found, failure = None, str(err)
    failure = built.model.agree(failure)
    if failure is not None:
        raise CaseError(failure)
    assert found is not None
    return found


def _restore(out: Path, built: Built, case_text: str, rank: int) -> tuple[Position, dict]:
    saved = checkpoint.load(out)  # CaseError if it is not a valid checkpoint
    if saved is None:
        raise CaseError(f"{out}: --resume: no checkpoint here (set [output] checkpoint_every to write them)")
    if saved.case_sha256 != checkpoint.text_sha256(case_text) and not _written_for(out, saved.case_sha256, case_text):
        raise CaseError(f"{out}: --resume: the case differs from the one the checkpoint was written for "
                        f"({out / 'case.toml'}); resume with the same case")
    position = _position(saved, out)
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
    model = built.model
    ranks = int(model.reduce_sum(1))
    if int(saved.run.get("ranks", 1)) != ranks:
        raise CaseError(f"{out}: --resume: the checkpoint was written by a run on {int(saved.run.get('ranks', 1))} "
                        f"MPI ranks; resume on as many (this run has {ranks})")
    if rank > 0:
        mine = checkpoint.load(out, checkpoint.rank_file(rank))
        if mine is None or int(mine.position.get("count", -1)) != position.count or mine.case_sha256 != saved.case_sha256:
            raise CaseError(f"{out / checkpoint.rank_file(rank)}: --resume: missing or not written with the "
                            f"checkpoint at step {position.count}; rerun with --overwrite")
        saved = mine
        position = _position(mine, out / checkpoint.rank_file(rank))
    signature = saved.position.get("local_dofs_sha256")
    if signature is not None and str(signature) != model.local_signature():
        raise CaseError(f"{out / checkpoint.rank_file(rank)}: --resume: the checkpoint was written for another "
                        "split of the model over the ranks (this rank's dofs differ); rerun with --overwrite")
    try:  # the model's vectors (an MPI rank's: on its local dofs)
        whole = model.checked_vector
        position = replace(position, u=whole(position.u),
                           f_int=None if position.f_int is None else whole(position.f_int),
                           u_before=None if position.u_before is None else whole(position.u_before))
    except ValueError as err:
        raise CaseError(f"{out}: --resume: the checkpoint was written for a different model (its displacement "
                        f"vector has {err})") from None
    groups = built.model.groups
    if len(saved.groups) != len(groups):
        raise CaseError(f"{out}: --resume: the checkpoint was written for a different model "
                        f"({len(saved.groups)} element groups, this case has {len(groups)})")
    try:
        for g, state in zip(groups, saved.groups):
            g.restore_checkpoint(state)
    except ValueError as err:
        raise CaseError(f"{out}: --resume: {err}") from None
    return position, saved.run


def _written_for(out: Path, digest: str, case_text: str) -> bool:
    """Whether out/case.toml is the text the checkpoint was written for (``digest``) and, read with
    today's schema, this case (a key added since then, at its default, is the same case)."""
    try:
        written = (out / "case.toml").read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError):
        return False
    return checkpoint.text_sha256(written) == digest and same_case(written, case_text)


def _position(saved: checkpoint.Saved, where: Path) -> Position:
    """The stepping position a checkpoint holds (CaseError if a field is missing)."""
    try:
        return position_from_arrays(saved.position)
    except KeyError as err:
        raise CaseError(f"{where}: --resume: the checkpoint has no position field {err}: written for a "
                        "different model") from None


def run_case(case: Case | str | Path, out: str | Path, progress: Callable[[dict], None] | None = None,
             path_label: str | None = None, resume: bool = False, overwrite: bool = False,
             warn: Callable[[str], None] | None = None, on_start: Callable[[], None] | None = None,
             watch: Callable[[Built], list[Observer]] | None = None,
             distribution: Distribution | None = None) -> RunSummary:
    """Run a validated case (or a case file) and write its outputs into ``out``.

    resume: continue from out/checkpoint.npz (written every [output] checkpoint_every steps) with the
    same case, after checking that the checkpoint, history.csv and the case belong together; the
    outputs are cut back to the checkpoint's step and continued, so the result is that of an
    uninterrupted run. A fresh run refuses a folder holding another run's outputs unless
    ``overwrite`` (which deletes them first). on_start(): called once the inputs are checked and the
    folder is ready, before the first step; warn: then called with each warning.
    SIGINT/SIGTERM end the run at the next step boundary (the summary's ``stop_signal`` says which).
    watch(built): more observers of the steps (e.g. the API's field snapshots), made once the model is built.
    distribution: run as one rank of an MPI run (rockfrac.parallel): every rank takes every step,
    rank 0 writes the outputs (from the ranks' gathered vectors and summed quantities).
    """
    label = path_label or (str(case) if not isinstance(case, Case) else "<case>")
    if not isinstance(case, Case):
        case = load_case(case)
    built = build(case, label, distribution)  # every input error surfaces here, before any step
    model = built.model
    lead = distribution is None or distribution.rank == 0  # the rank that writes
    history = make_history(built, label)
    case_text = resolved_text(built.case)
    failed = None
    if lead:
        try:
            out = prepare_output(out, OUTPUTS, overwrite=overwrite, resume=resume)
        except CaseError as err:
            failed = str(err)
    failed = model.share(failed)  # the other ranks stop with rank 0
    if failed is not None:
        raise CaseError(failed)
    out = Path(out)
    start: Position | None = None
    counters: dict[str, float] = {}
    if resume:
        start, counters = _resume(out, built, case_text, distribution.rank if distribution is not None else 0)
        history.restore({"work": np.array(counters.get("work", 0.0)),
                         "released": np.array(counters.get("released", 0.0)), "u_prev": start.u,
                         "f_prev": start.f_int if start.f_int is not None else np.zeros(built.model.n_dofs)})
        history.after_cuts(start.u, np.zeros(built.model.n_dofs))  # f_int does not depend on the loads
    case_sha = checkpoint.text_sha256(case_text)
    if lead:
        (out / "case.toml").write_text(case_text, encoding="utf-8")
    keep = start.count if start is not None else None
    # the peak magnitudes the stop rules have seen (checkpointed as run.stop_peak.<quantity>)
    peaks = {k.removeprefix("stop_peak."): float(v) for k, v in counters.items() if k.startswith("stop_peak.")}
    run = {"iters": int(counters.get("iters", 0)), "last": keep or 0}
    events: list[str] = []  # the groups' event lines of every rank, in the order they came
    sent = [0] * len(model.groups)  # how many of each group's lines this rank has passed on

    def gather_events() -> None:  # a collective call: each group's new lines of every rank, appended
        for k, g in enumerate(model.groups):
            lines = g.event_log()
            for new in model.allgather(lines[sent[k]:]):
                events.extend(new)
            sent[k] = len(lines)

    gather_events()
    log: RunLog | Quiet = (RunLog(out / "run.log", keep, lambda: events, _pieces_at(out / "history.csv", keep))
                           if lead else Quiet())
    observers: list[Observer] = []
    try:
        hist = HistoryCsv(out / "history.csv", history.columns, keep) if lead else None
        if hist is not None:
            observers.append(hist)
        if lead and case.output.points and (built.cohesives or built.embeddeds):
            # 3D surfaces have (t1, t2, n) components; a plane-strain hex8 specimen's cracks are 2D
            general = [g for g in built.embeddeds if g.dim == 3 and not g.plane_strain]
            columns = POINT_COLUMNS_3D if any(g.dim == 3 for g in built.cohesives) or general else POINT_COLUMNS
            extra = [n for g in built.cohesives for n in g.law.record_names if n not in columns]
            extra += ["gamma", "zeta", "c_p"] if general else []
            observers.append(PointsCsv(out / "points.csv", columns + list(dict.fromkeys(extra)), keep))
        if lead and history.fragments is not None:
            observers.append(FragmentsCsv(out / "fragments.csv", lambda: history.pieces))
        if case.output.vtk:  # an MPI run: one piece per rank and rank 0's .pvtu joining them
            from rockfrac.output.fields import step_output, step_piece

            if distribution is None:
                observers.append(VtkSeriesWriter(out / "vtk", case.output.vtk_every,
                                                 lambda u: step_output(built, u), keep))
            else:
                ranks = int(model.reduce_sum(1))

                def barrier() -> None:
                    model.agree(None)

                if not lead:  # rank 0 made the folder (and deleted an old series) before the others go on
                    barrier()
                observers.append(VtkSeriesWriter(out / "vtk", case.output.vtk_every, lambda u: step_piece(built, u),
                                                 keep, (distribution.rank, ranks, barrier)))
                if lead:
                    barrier()
        observers.append(log)
        if progress is not None and lead:
            observers.append(Progress(progress))
        if watch is not None and lead:
            observers.extend(watch(built))
        axial_peak = {"F_axial": float(counters.get("peak", -np.inf))}

        def counts() -> dict[str, float]:
            return {"peak": axial_peak["F_axial"], "iters": run["iters"], "work": history.work,
                    "released": history.released,
                    **{f"stop_peak.{q}": v for q, v in peaks.items()}}

        observers.append(Checkpoints(out, case.output.checkpoint_every, model, counts, hist, case_sha, log,
                                     distribution.rank if distribution is not None else 0))
        observers.append(StopRules(built.program.stops, peaks))
        if start is not None:
            log(f"resumed from the checkpoint at step {start.count}")
        mesh = built.mesh
        n_cells, n_nodes, n_if = (mesh.place.n_cells, mesh.place.n_nodes, mesh.place.n_interfaces) \
            if mesh.place is not None else (mesh.cells.shape[0], mesh.n_nodes, mesh.interfaces.shape[0])
        log(f"model: {n_cells} {mesh.cell_type} cells, {n_nodes} nodes"
            + (f", {n_if} interface cells" if n_if else "") + f", {model.n_dofs_global} unknowns")
        for note in built.program.notes + history.notes:
            log(note)
        for c, group in zip(case.cohesive_sets, built.cohesives):
            if c.viscosity is not None:
                which = f"{group.name}, " if len(case.cohesive_sets) > 1 else ""
                log(f"cohesive surfaces ({which}{c.where.value}): viscous (Duvaut-Lions) regularisation, relaxation time "
                    f"{c.viscosity:g} (pseudo-time, a stage = 1); its extra dissipation is history.csv's D_viscous")
        if distribution is not None:
            log(f"MPI: {model.reduce_sum(1)} ranks, the mesh split by METIS ({n_cells} cells, "
                f"{n_if} interface cells), each rank building on its piece of it")
        if on_start is not None and lead:
            on_start()
        warnings = case_warnings(built)
        for w in warnings:
            log(f"warning: {w}")
            if warn is not None and lead:
                warn(w)

        def on_step(info: StepInfo) -> None:  # on MPI ranks, u and f_int are on the rank's local dofs
            rec = point_rows(built, info.u)
            row = history.row(info, rec)
            gather_events()
            run["iters"] += info.newton.iterations
            run["last"] = info.step
            if "F_axial" in row and info.stage.startswith("axial"):
                axial_peak["F_axial"] = max(axial_peak["F_axial"], row["F_axial"])
            step = Step(info, row, rec)
            for obs in observers:
                obs.step(step)

        sol = case.solver
        t0 = time.perf_counter()
        with stop_on_signals() as request:
            stop = request if distribution is None else (lambda: model.reduce_any(request()))
            newton, stepping = engine_options(built, stop)
            enriched = any(isinstance(g, HeldEnrichment) for g in built.model.groups)
            if distribution is None:
                solver = make_solver(sol.linear, built.mesh.nodes, built.model.n_dofs, enrichment=enriched)
            else:
                solver = distribution.make_solver(sol.linear.value, built.model.n_dofs_global, built.mesh.dim, enriched)
            log(f"linear solver: {solver.name} ([solver] linear = '{sol.linear.value}')")
            result = run_stages(built.model, built.stages, solver, newton, stepping, on_step, log,
                                start=start, should_stop=stop, u0=built.program.u0, f0=built.program.f0)
    except KeyboardInterrupt:
        log(f"end: interrupted (repeated SIGINT) after step {run['last']}; every converged step is kept")
        log.close()
        raise RunStopped(f"interrupted (repeated SIGINT) after step {run['last']}; every converged step is kept in "
                         f"{out}", 130) from None
    except BaseException:
        log.close()
        raise
    finally:
        for obs in observers:
            if obs is not log:
                obs.close()
    wall = time.perf_counter() - t0
    peak = axial_peak["F_axial"] if built.case.loading is not None else float("nan")
    if result.stopped:
        log(f"end: stopped by {request.reason} after {result.steps} steps, {wall:.3f} s; every converged step is "
            "kept" + (" (rockfrac run --resume continues from the last checkpoint)"
                      if case.output.checkpoint_every else ""))
        for note in solver.notes():
            log(f"linear solver: {note}")
        log.close()
        return RunSummary(result, out, wall, peak, run["iters"], built, warnings,
                          stop_signal=request.reason, exit_code=request.exit_code)
    log(f"end: {result.message} after {result.steps} steps, {wall:.3f} s")
    for note in solver.notes():
        log(f"linear solver: {note}")
    if history.pieces is not None and history.pieces.count > 1:
        sizes = ", ".join(f"{v:.4g}" for v in history.pieces.size[:3]) + (", ..." if history.pieces.count > 3 else "")
        log(f"fragments: the body ends in {history.pieces.count} pieces of {sizes} "
            f"{'m^3' if built.mesh.dim == 3 else 'm^2'} (fragments.csv)")
    if history.viscous:
        total = history.dissipated()
        log(f"viscous regularisation: D_viscous = {history.viscous_dissipated():.6g} of D_dissipated = {total:.6g} "
            "(the rest is the traction laws' own)")
    try:
        if case.output.picture:
            from rockfrac.output.crack_map import save_crack_map
            from rockfrac.output.fields import step_output, step_piece
            from rockfrac.output.plots import magnification
            from rockfrac.output.vtk import join_pieces

            view = "3d" if built.mesh.dim == 3 and case.mesh.kind.value != "specimen" else "plane"
            if distribution is None:
                fields, u_all = step_output(built, result.u), result.u
            else:  # every rank's piece (collective), joined on rank 0
                pieces = model.gather_lead(step_piece(built, result.u))
            if lead:
                if distribution is not None:
                    assert pieces is not None and built.whole is not None
                    fields = join_pieces(pieces)
                    u_all = fields.point_data["displacement"][:built.whole.n_nodes, :built.whole.dim].ravel()
                mag = magnification(built, u_all, mesh=built.whole)
                cracks = save_crack_map(out / "crack_map.png", fields, mag, view=view,
                                        title=f"{case.title or 'rockfrac run'}: step {result.steps}, deformed "
                                              f"x{mag:g}")
                what = "crack segments" if view == "plane" else "yielded interface cells and surface triangles"
                log(f"crack_map.png: step {result.steps}, {cracks.opening.size} {what}, deformed x{mag:g}")
    finally:
        log.close()
    return RunSummary(result, out, wall, peak, run["iters"], built, warnings)


def engine_options(built: Built, should_stop: Callable[[], bool] | None = None
                   ) -> tuple[NewtonOptions, SteppingOptions]:
    """Newton's and the stepping's options from the case's [solver] section."""
    case, sol = built.case, built.case.solver
    stepping = SteppingOptions(cutback=sol.cutback, min_step=sol.min_step, grow=sol.grow,
                               easy_iterations=sol.easy_iterations, locate_activation=sol.locate_activation,
                               fallback=sol.fallback, implex_tol=sol.implex_tol)
    newton = NewtonOptions(sol.max_iterations, sol.tol_residual, sol.tol_energy,
                           force_scale=1e-6 * max(m.E for m in case.material_list) * _size(built),
                           eliminate=bool(sol.elimination), should_stop=should_stop)
    return newton, stepping


def _size(built: Built) -> float:
    """The Newton force scale's length: the specimen width for the [loading] form (the paper's
    scale), else the mesh's extent along x [m]."""
    if built.case.loading is not None:
        return built.case.mesh.width
    lo, hi = built.mesh.bounds  # the whole mesh's, also on an MPI rank's piece of it
    return float(hi[0] - lo[0]) or 1.0
