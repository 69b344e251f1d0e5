"""Load stepping: stages of linearly ramped loads, automatic cutback, path following, clean stop.

A stage ramps the prescribed displacements and the external forces from their values at its
start to its end values with a load factor lam: 0 -> 1. Steps are load-controlled (lam given)
until the stage's ``path`` (if any) becomes active, or a load-controlled step fails where the
path is available (a limit point, or a snap-back at activation); from then on each step prescribes an
increment of a path measure (:mod:`rockfrac.solve.paths`) and lam is solved for, so limit points
and snap-backs are traced. A step in which an event indicator of the model (the loss of
ellipticity of a Drucker-Prager cell) crosses zero is shortened to end at the event. Each
converged step is committed and handed to ``on_step``; a failed
step is retried with a smaller increment down to ``min_step``, where the run stops cleanly,
keeping every converged step.

After an easy step the increment grows back (by ``grow``, up to the nominal one). Easy is judged on
Newton's iterations without an active-set change (a cohesive point switching between elastic or
constrained and plastic, an embedded crack between sticking and sliding). With many surfaces
yielding, points switch in most iterations of a step whatever its size, so counting those
iterations kept a cut-back step small for the rest of the run (benchmarks/README.md, "Step growth").

After a commit that cut cells of a crack growing at its tips (the nodal embedded crack:
``Model.growth_waiting``), the next step is a "hold": equilibrium at the same load factor, or under
path control at the same value of the path measure (the load may fall: a snap-back), committed like
any step. The cells at the new tips that the stress before the cuts already drives wait for the
stress after them, and the hold's commit opens those it drives. A crack thus runs as far as the load
already applied drives it before the load moves on (otherwise how far it ran in a step was set by
the step's size). A hold that does not converge is dropped and the stepping goes on.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from rockfrac.model import Model
from rockfrac.solve.events import activation_fraction, pending, yielded
from rockfrac.solve.linear import LinearSolver
from rockfrac.solve.newton import Loads, NewtonOptions, NewtonResult, PathControl, newton_step, points
from rockfrac.solve.paths import Committed, PathSpec


@dataclass(frozen=True)
class Stage:
    """One ramp: ``steps`` equal increments of the load factor unless cut back.

    dirichlet: the dofs prescribed during the stage, dirichlet_end their values at its end (each
    ramps from its value at the stage start: the previous stage's end value, or the displacement
    reached if it was free). None: the model's current Dirichlet set, dirichlet_end in its order.
    """

    name: str
    steps: int
    dirichlet_end: np.ndarray  # prescribed values at the end of the stage
    f_ext_end: np.ndarray  # external forces at the end of the stage
    path: PathSpec | None = None
    source: str = ""  # the input that sets this stage's loads, named in a failure ("[loading] confinement")
    dirichlet: np.ndarray | None = None  # the stage's prescribed dofs (sorted)
    # tractions on boundary sides at the end of the stage, (m, s) mesh nodes (edges in 2D, faces in 3D)
    # and their values at those nodes (m, s, dim) [Pa]: what a crack with enriched unknowns needs to
    # split a boundary's load between its two sides
    surface_edges: np.ndarray | None = None
    surface_tractions: np.ndarray | None = None
    # the same at t = 0, on the first stage (the in-situ tractions of the forces f0 it starts from)
    start_edges: np.ndarray | None = None
    start_tractions: np.ndarray | None = None
    # body forces per region at the end of the stage [N/m^3] (gravity: density x g), and at t = 0 on
    # the first stage: the enriched unknowns' share of them
    body_force: dict[str, np.ndarray] | None = None
    start_body_force: dict[str, np.ndarray] | None = None

    def end_values(self, dofs: np.ndarray, start: np.ndarray) -> np.ndarray:
        """Prescribed values at the end of the stage on ``dofs`` (the model's Dirichlet set in this
        stage): the stage's own where it prescribes them, ``start`` (held) on the others (the extra
        dofs the model prescribes because the Dirichlet set makes them redundant)."""
        if self.dirichlet is None:
            return self.dirichlet_end
        pos = np.searchsorted(self.dirichlet, dofs)
        pos = np.minimum(pos, max(self.dirichlet.shape[0] - 1, 0))
        own = self.dirichlet.shape[0] > 0
        hit = (self.dirichlet[pos] == dofs) if own else np.zeros(dofs.shape[0], dtype=bool)
        return np.where(hit, self.dirichlet_end[pos] if own else 0.0, start)


@dataclass(frozen=True)
class SteppingOptions:
    cutback: float = 0.5
    min_step: float = 1e-4  # smallest increment, as a fraction of the nominal one
    grow: float = 1.5  # increment growth after an easy step, up to the nominal one
    easy_iterations: int = 6  # a step is easy if its iterations without an active-set switch are at most this
    event_tol: float = 1e-4  # a step may end this far past an event (indicator in [-tol, 0])
    locate_activation: bool = False  # end a load step where a surface first yields (its peak)
    fallback: str = "none"  # "implex": a step failing at min_step switches EP surfaces to IMPL-EX
    implex_tol: float = 0.05  # largest IMPL-EX traction error of a step, relative to the law's strength


@dataclass
class Position:
    """Where the stepping is after a converged step: enough, with the model's committed state, to
    continue exactly as an uninterrupted run would (a checkpoint)."""

    stage: int  # index of the current stage
    lam: float  # its load factor
    u: np.ndarray
    count: int  # converged steps so far
    stage_steps: int
    size: dict  # next increments: {"load": ..., "path": ...}
    forced: bool  # path control taken over after a failed load step
    d_start: np.ndarray | None = None  # prescribed values at the start of the current stage
    f_int: np.ndarray | None = None  # internal forces of the last converged step
    u_before: np.ndarray | None = None  # u one converged step earlier in this stage (arc length)
    path_nominal: float | None = None  # the stage's nominal path increment, once known


@dataclass
class StepInfo:
    stage: str
    step: int
    load_factor: float
    u: np.ndarray
    f_int: np.ndarray
    newton: NewtonResult
    cutbacks: int
    controlled_by: str  # "load" or "path"
    position: Position | None = None
    f_ext: np.ndarray | None = None  # external forces of the step
    stage_index: int = 0


@dataclass
class RunResult:
    completed: bool
    steps: int
    message: str
    u: np.ndarray
    stopped: bool = False  # ended by a stop request (should_stop), every converged step kept


class StopRun(Exception):
    """Raised by ``on_step`` to end the run early (e.g. past the requested softening)."""


def _log_iterations(log, name: str, step: int, res: NewtonResult) -> None:
    switched = res.switched + [0] * (len(res.residuals) - len(res.switched))
    local = dict(zip(res.eliminated, res.eliminated_unknowns))  # iterate it + 1 came from a local solve
    augmented = dict(zip(res.augmented, res.gaps))  # iterate it updated the nested multipliers
    for k, (rr, ee, n) in enumerate(zip(res.residuals, [np.nan] + res.energies, switched)):
        change = f", {points(n)} switched" if k and n else ""
        if k - 1 in local:
            change += f", after a local solve of {local[k - 1]} unknown{'s' if local[k - 1] != 1 else ''} (elimination)"
        if k in augmented:
            change += f", multipliers updated (nested: their rows were at {augmented[k]:.3e})"
        log(f"  {name} step {step} it {k}: residual {rr:.3e} energy {ee:.3e}{change}")


def run_stages(
    model: Model,
    stages: list[Stage],
    solver: LinearSolver,
    newton: NewtonOptions,
    stepping: SteppingOptions,
    on_step: Callable[[StepInfo], None],
    log: Callable[[str], None] = lambda s: None,
    start: Position | None = None,
    should_stop: Callable[[], bool] | None = None,
    u0: np.ndarray | None = None,
    f0: np.ndarray | None = None,
) -> RunResult:
    """Run the stages in order from u0 (default 0) under the external forces f0 (default 0, the
    forces in equilibrium with the initial state), or from ``start`` with the model's committed
    state restored to it; returns after the last stage or a clean stop.

    Each stage prescribes its own Dirichlet set (``Stage.dirichlet``); a dof prescribed in the
    previous stage starts from that stage's end value, a newly prescribed one from its current
    displacement. should_stop: asked before every step (and by Newton before every iteration,
    through its options); once true the run returns with ``stopped`` set, the last step being the
    last converged.
    """

    def stopped(stage: Stage) -> RunResult:
        return RunResult(False, count, f"stop requested in stage {stage.name!r} after step {count}", u, stopped=True)

    if start is not None:
        u = start.u.copy()
    else:
        u = np.zeros(model.n_dofs) if u0 is None else u0.copy()
    f_start = np.zeros(model.n_dofs) if f0 is None else f0
    u_ref = np.zeros(model.n_dofs) if u0 is None else u0.copy()  # the initial state (energy released from it)
    f_ref = f_start
    previous = np.full(model.n_dofs, np.nan)  # prescribed values at the end of the last stage (nan: free)
    count = 0 if start is None else start.count
    refresh = _EnrichedLoads(model, stages, f_start)
    for index, stage in enumerate(stages):
        if start is not None and index < start.stage:
            previous = _end_map(model, stage, previous)
            f_start = stage.f_ext_end
            continue
        if stage.dirichlet is not None:
            model.set_dirichlet(stage.dirichlet)
        dofs = model.dirichlet
        if start is not None and index == start.stage and start.d_start is not None:
            d_start = start.d_start
        else:
            d_start = np.where(np.isnan(previous[dofs]), u[dofs], previous[dofs])
        d_end = stage.end_values(dofs, d_start)
        refresh()
        loads = Loads(d_start, d_end - d_start, f_start, stage.f_ext_end - f_start)
        lam, cutbacks, stage_steps = 0.0, 0, 0
        hold_failed = -1  # the step count at which the last re-solve at the same load failed
        last_size: dict[str, float] = {}  # the increment of the last converged step, by control
        path_nominal = stage.path.increment if stage.path else None
        nominal = {"load": 1.0 / stage.steps, "path": path_nominal or 0.0}
        size = dict(nominal)
        forced = False  # path control taken over after a failed load-controlled step
        u_before: np.ndarray | None = None
        if start is not None and index == start.stage:
            lam, stage_steps, size, forced = start.lam, start.stage_steps, dict(start.size or nominal), start.forced
            u_before, path_nominal = start.u_before, start.path_nominal or path_nominal
            nominal["path"] = path_nominal or 0.0
        while lam < 1.0 - 1e-12:
            if should_stop is not None and should_stop():
                return stopped(stage)
            committed = Committed(u, u_before, lam, loads, u_ref, f_ref)
            constraint = None
            hold = hold_failed != count and model.growth_waiting()
            if stage.path is not None and (forced or stage.path.active()):
                constraint = stage.path.constraint(committed)  # frozen at the committed state
            if constraint is not None and path_nominal is None:
                constraint = None  # the nominal increment comes from the first step
            # a hold (after cuts): equilibrium at the same load, or under path control at the same value
            # of the path measure (the load free to fall: a snap-back)
            if constraint is not None:
                mode = "hold" if hold else "path"
                assert stage.path is not None
                increment = 0.0 if hold else size["path"]
                ctrl = PathControl(constraint.measure, constraint.value(u, lam) + increment, 1e-9 * nominal["path"],
                                   size["load"] * size["path"] / nominal["path"], stage.path.rigid_ok,
                                   constraint.lam_coeff)

                def path_step() -> NewtonResult:
                    model.set_step("path", increment)
                    out = newton_step(model, u, lam, lam, loads, solver, newton, ctrl)
                    if not hold and out.converged and out.lam > 1.0 - 1e-12:  # land exactly on the stage end
                        model.set_step("load", 1.0 - lam)
                        out = newton_step(model, u, lam, 1.0, loads, solver, newton)
                    return out

                locate = not hold and stepping.locate_activation and pending(model)
                res = path_step()
                if locate and res.converged and yielded(model):
                    # a surface yielded in the step (it may have passed its peak, the load falling): end the
                    # step where the first point yields along the response before it, as a load step
                    reach = min(1.0 - lam, max(size["load"], abs(res.lam - lam)))
                    s = activation_fraction(model, u, lam, reach, loads, solver)
                    target = lam + s * reach if s is not None and s < 1.0 else lam
                    if target - lam >= stepping.min_step * nominal["load"]:
                        log(f"  {stage.name}: a surface first yields in the path step, at load factor "
                            f"{target:.9f}; ending the step there")
                        model.set_step("load", target - lam)
                        res = newton_step(model, u, lam, target, loads, solver, newton)
                        mode = "load" if res.converged else mode  # a failed one cuts the path step back
                    else:  # no activation to end on: the step as it was (the prediction reset the trial state)
                        res = path_step()
            elif hold:
                mode = "hold"
                model.set_step("load", 0.0)
                res = newton_step(model, u, lam, lam, loads, solver, newton)
            else:
                mode = "load"
                size["load"] = min(size["load"], 1.0 - lam)
                step = size["load"]
                if stepping.locate_activation:
                    s = activation_fraction(model, u, lam, step, loads, solver)
                    if s is not None and s < 1.0 and s * step >= stepping.min_step * nominal["load"]:
                        step *= s
                        log(f"  {stage.name}: a surface first yields {s:.6f} of the way through the step; "
                            f"ending it there (load factor {lam + step:.9f})")
                model.set_step("load", step)
                res = newton_step(model, u, lam, lam + step, loads, solver, newton)
            _log_iterations(log, stage.name, count + 1, res)
            if res.interrupted:
                return stopped(stage)
            if hold and not res.converged:
                hold_failed = count
                log(f"  {stage.name}: no equilibrium after the last cuts at load factor {lam:.6f} (or its "
                    f"path measure) ({res.message}); stepping on")
                continue
            if (not res.converged and mode == "load" and stage.path is not None and not forced
                    and (m := stage.path.constraint(committed)) is not None
                    and model.reduce_any(bool(np.any(m.measure(u)[1])))):
                # a limit point under load control, and a path measure that can respond (a
                # discontinuity exists): follow the path from here; otherwise cut the load step back
                forced = True
                log(f"  {stage.name}: load-controlled step from lam={lam:.6f} failed ({res.message}); "
                    "switching to path control")
                continue
            if not res.converged:
                cutbacks += 1
                log(f"  {stage.name}: {mode}-controlled step from lam={lam:.6f} (size {size[mode]:.3e}) "
                    f"failed: {res.message}; cutting back")
                size[mode] *= stepping.cutback
                if (size[mode] < stepping.min_step * nominal[mode] * (1 - 1e-12) and stepping.fallback == "implex"
                        and model.switch_to_implex()):
                    log(f"  {stage.name}: step from lam={lam:.6f} failed at min_step; the EP cohesive surfaces "
                        "switch to IMPL-EX integration for the rest of the run ([solver] fallback)")
                    size[mode] = last_size.get(mode, nominal[mode])  # the extrapolation's own step: ratio 1
                    continue
                if size[mode] < stepping.min_step * nominal[mode] * (1 - 1e-12):
                    source = f" (loads from {stage.source})" if stage.source else ""
                    return RunResult(False, count, f"stopped in stage {stage.name!r}{source} at load factor "
                                     f"{lam:.6f}: {mode} increment below min_step after {cutbacks} "
                                     f"cutbacks ({res.message})", u)
                continue
            implex = model.implex_error()  # IMPL-EX's error in the step: first order in its size
            if implex is not None and implex > stepping.implex_tol and not hold:
                shrink = max(0.1, 0.8 * stepping.implex_tol / implex)
                if size[mode] * shrink >= stepping.min_step * nominal[mode]:
                    log(f"  {stage.name}: IMPL-EX error {implex:.3g} > {stepping.implex_tol:g} in the step; "
                        f"shortening it by {shrink:.3f}")
                    size[mode] *= shrink
                    continue
                log(f"  {stage.name}: warning: IMPL-EX error {implex:.3g} > {stepping.implex_tol:g} in a step "
                    "at min_step; the step is kept with that error (a shorter one would be below min_step)")
            crossing = model.event()
            if (not hold and crossing is not None and crossing[0] > stepping.event_tol
                    and crossing[1] < -stepping.event_tol):
                before, after = crossing  # end the step at the event: secant on the step size
                frac = min(0.9, max(0.05, before / (before - after)))
                if size[mode] * frac >= stepping.min_step * nominal[mode]:
                    log(f"  {stage.name}: event indicator {before:.3e} -> {after:.3e} in the step; "
                        f"shortening it by {frac:.3f} to land on the event")
                    size[mode] *= frac
                    continue
            model.commit()
            if refresh():  # a crack crossed into a loaded boundary's cells: its share of the loads
                loads = Loads(loads.d0, loads.dd, f_start, stage.f_ext_end - f_start)
            if not hold:
                last_size = {mode: size[mode] if mode == "path" else res.lam - lam}
            if stage.path is not None and path_nominal is None and not hold:
                first = stage.path.constraint(Committed(res.u, u, res.lam, loads, u_ref, f_ref))
                change = 0.0 if first is None else abs(first.value(res.u, res.lam) - first.value(u, lam))
                if change > 0.0:  # the measure's change over a nominal load step, from the first step
                    path_nominal = change * nominal["load"] / (res.lam - lam)
                    nominal["path"] = size["path"] = path_nominal
            if not hold:  # the arc length's direction stays the last load step's
                u_before = u
            u, lam = res.u, res.lam
            count += 1
            stage_steps += 1
            step_cutbacks, cutbacks = cutbacks, 0
            if not hold and res.iterations - res.switching_iterations <= stepping.easy_iterations:
                grow = stepping.grow
                if implex is not None:  # IMPL-EX: no faster than its error allows
                    grow = min(grow, 0.8 * stepping.implex_tol / max(implex, 1e-300))
                size[mode] = min(nominal[mode], size[mode] * max(grow, 1.0))
            done = lam >= 1.0 - 1e-12
            position = Position(index + 1 if done else index, 0.0 if done else lam, u, count,
                                0 if done else stage_steps, {} if done else dict(size), False if done else forced,
                                None if done else d_start, res.f_int, None if done else u_before,
                                None if done else path_nominal)
            assert res.f_int is not None  # a converged step has its internal forces
            try:
                on_step(StepInfo(stage.name, count, lam, u, res.f_int, res, step_cutbacks, mode, position,
                                 loads.forces(lam), index))
            except StopRun as stop:
                return RunResult(True, count, str(stop), u)
            if stage.path is not None and stage_steps >= stage.path.max_steps:
                return RunResult(False, count, f"stage {stage.name!r} reached its maximum of "
                                 f"{stage.path.max_steps} steps at load factor {lam:.6f}", u)
        previous = _end_map(model, stage, previous, d_end)
        f_start = stage.f_ext_end
    return RunResult(True, count, "all stages completed", u)


class _EnrichedLoads:
    """Keeps the stages' external forces on a model's enriched unknowns (a crack's, see
    rockfrac.elements.ede_enrichment) up to date: called after every change, it adds to each stage's
    own forces the share of its boundary tractions and body forces that the enrichment takes now
    (in place, so that a stage's start forces, the previous stage's end ones, follow), and to the
    forces f0 the run starts from the share of the first stage's ``start_*`` loads. Returns True if
    they changed."""

    def __init__(self, model: Model, stages: list[Stage], f0: np.ndarray | None = None):
        self.model = model
        self.stages = stages
        first = stages[0] if stages else None

        def anywhere(flag) -> bool:  # on any MPI rank: each holds the loaded sides of its piece only
            return bool(model.reduce_max(1.0 if flag else 0.0))

        self.sides = [anywhere(s.surface_edges is not None and s.surface_edges.size) for s in stages]
        self.bodies = [anywhere(_loaded(s.body_force)) for s in stages]
        self.start_sides = first is not None and anywhere(first.start_edges is not None and first.start_edges.size)
        self.start_body = first is not None and anywhere(_loaded(first.start_body_force))
        self.f0 = f0 if self.start_sides or self.start_body else None
        self.active = model.enrichment_version() is not None and (self.f0 is not None or any(self.sides)
                                                                  or any(self.bodies))
        self.own = [s.f_ext_end.copy() for s in stages] if self.active else []
        self.own0 = self.f0.copy() if self.active and self.f0 is not None else None
        self.seen: tuple[int, ...] | None = None

    def __call__(self) -> bool:
        if not self.active:
            return False
        version = self.model.enrichment_version()
        if version == self.seen:
            return False
        self.seen = version
        for k, (stage, own) in enumerate(zip(self.stages, self.own)):
            stage.f_ext_end[:] = own + self._share(stage.surface_edges, stage.surface_tractions, stage.body_force,
                                                   self.sides[k], self.bodies[k])
        first = self.stages[0]
        if self.f0 is not None and self.own0 is not None:
            self.f0[:] = self.own0 + self._share(first.start_edges, first.start_tractions, first.start_body_force,
                                                 self.start_sides, self.start_body)
        return True

    def _share(self, edges: np.ndarray | None, tractions: np.ndarray | None, body: dict[str, np.ndarray] | None,
               sides: bool, bodies: bool) -> np.ndarray | float:
        """The enriched unknowns' share of boundary tractions and body forces (0.0: none), made where
        some MPI rank has loaded sides (``sides``) or bodies (``bodies``): the sums are collective, and
        a rank's piece may hold none of the loaded sides."""
        out: np.ndarray | float = 0.0
        if sides:
            if edges is None or tractions is None or not edges.size:
                edges, tractions = np.zeros((0, 2), dtype=np.int64), np.zeros((0, 2, self.model.dim))
            out = out + self.model.enriched_surface_forces(edges, tractions)
        if bodies:
            out = out + self.model.enriched_body_forces(body or {})
        return out


def _loaded(body: dict[str, np.ndarray] | None) -> bool:
    """Body forces that are not zero somewhere."""
    return body is not None and any(np.any(b) for b in body.values())


def _end_map(model: Model, stage: Stage, previous: np.ndarray, d_end: np.ndarray | None = None) -> np.ndarray:
    """Prescribed values (nan: free) over all dofs at the end of ``stage``."""
    out = np.full(model.n_dofs, np.nan)
    if stage.dirichlet is None:
        out[model.dirichlet] = stage.dirichlet_end if d_end is None else d_end
    else:
        out[stage.dirichlet] = stage.dirichlet_end
    return out
