"""Load stepping: stages of linearly ramped loads, automatic cutback, clean stop.

A stage ramps the prescribed displacements and the external force vector from their values at
its start to its end values with a load factor 0 -> 1. Each converged step is committed and
handed to ``on_step``; a step that fails is retried with a smaller increment until ``min_step``,
where the run stops cleanly, keeping every converged step.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from rockfrac.model import Model
from rockfrac.solve.linear import LinearSolver
from rockfrac.solve.newton import NewtonOptions, NewtonResult, newton_step


@dataclass(frozen=True)
class Stage:
    """One ramp: ``steps`` equal increments of the load factor unless cut back."""

    name: str
    steps: int
    dirichlet_end: np.ndarray  # prescribed values at the end of the stage
    f_ext_end: np.ndarray  # external forces at the end of the stage


@dataclass(frozen=True)
class SteppingOptions:
    cutback: float = 0.5
    min_step: float = 1e-4  # smallest load-factor increment, as a fraction of the stage
    grow: float = 1.5  # increment growth after an easy step, up to the stage's nominal one
    easy_iterations: int = 6


@dataclass
class StepInfo:
    stage: str
    step: int
    load_factor: float
    u: np.ndarray
    f_int: np.ndarray
    newton: NewtonResult
    cutbacks: int


@dataclass
class RunResult:
    completed: bool
    steps: int
    message: str
    u: np.ndarray


class StopRun(Exception):
    """Raised by ``on_step`` to end the run early (e.g. past the requested softening)."""


def run_stages(
    model: Model,
    stages: list[Stage],
    solver: LinearSolver,
    newton: NewtonOptions,
    stepping: SteppingOptions,
    on_step: Callable[[StepInfo], None],
    log: Callable[[str], None] = lambda s: None,
) -> RunResult:
    """Run the stages in order from u = 0; returns after the last stage or a clean stop."""
    u = np.zeros(model.n_dofs)
    d_start = np.zeros(model.dirichlet.shape[0])
    f_start = np.zeros(model.n_dofs)
    step_count = 0
    for stage in stages:
        nominal = 1.0 / stage.steps
        dlam = nominal
        lam = 0.0
        cutbacks = 0
        while lam < 1.0 - 1e-12:
            dlam = min(dlam, 1.0 - lam)
            target = lam + dlam
            d_target = d_start + target * (stage.dirichlet_end - d_start)
            f_target = f_start + target * (stage.f_ext_end - f_start)
            res = newton_step(model, u, d_target, f_target, solver, newton)
            for k, (rr, ee) in enumerate(zip(res.residuals, [np.nan] + res.energies)):
                log(f"  {stage.name} step {step_count + 1} it {k}: residual {rr:.3e} energy {ee:.3e}")
            if not res.converged:
                cutbacks += 1
                log(f"  {stage.name}: step from {lam:.6f} by {dlam:.3e} failed ({res.message}); cutting back")
                dlam *= stepping.cutback
                if dlam < stepping.min_step * nominal * (1 - 1e-12):
                    msg = (f"stopped in stage {stage.name!r} at load factor {lam:.6f}: increment below "
                           f"min_step after {cutbacks} cutbacks ({res.message})")
                    return RunResult(False, step_count, msg, u)
                continue
            model.commit()
            u = res.u
            lam = target
            step_count += 1
            try:
                on_step(StepInfo(stage.name, step_count, lam, u, res.f_int, res, cutbacks))
            except StopRun as stop:
                return RunResult(True, step_count, str(stop), u)
            cutbacks = 0
            if res.iterations <= stepping.easy_iterations:
                dlam = min(nominal, dlam * stepping.grow)
        d_start, f_start = stage.dirichlet_end, stage.f_ext_end
    return RunResult(True, step_count, "all stages completed", u)
