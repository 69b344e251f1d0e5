"""Events located inside a load step: the first activation of a cohesive surface (its peak).

While a surface has not yielded anywhere, the response to a load increment from the committed state
is the linear one of the committed tangent; along it each point's traction moves on a straight line,
and the fraction of the increment at which the first point meets its yield surface is found by
bisection (:meth:`rockfrac.elements.base.ElementGroup.activation`). The stepping then ends the step
there, so the activation (the peak of a brittle crack) is a converged step rather than stepped over.
A path-controlled step (arc length, energy) whose converged state has yielded from a pending one is
located alike, along its own load increment, and redone as a load step to the activation.
"""

from __future__ import annotations

import numpy as np

from rockfrac.elements.base import ElementGroup
from rockfrac.model import Model
from rockfrac.solve.linear import LinearSolver
from rockfrac.solve.newton import Loads


def activation_fraction(model: Model, u: np.ndarray, lam: float, dlam: float, loads: Loads,
                        solver: LinearSolver) -> float | None:
    """The fraction of the load increment lam -> lam + dlam at which a pending surface first
    yields along the committed tangent's response, or None (none pending, or none yields)."""
    groups = _pending(model)
    if not groups:
        return None
    model.begin_step()  # the trial state is the committed one: the tangent at u
    asm = model.assemble(u, u, loads.forces(lam))
    if not asm.ok:  # the same on every rank of a distributed model
        return None
    dofs_d = model.dirichlet
    a = asm.matrix
    lift = np.zeros_like(u)
    lift[dofs_d] = dlam * loads.dd
    rhs = dlam * loads.df - a @ lift
    rhs[dofs_d] = dlam * loads.dd
    try:
        du: np.ndarray | None = solver.factorize(model.apply_dirichlet(a)).solve(rhs)
        if du is not None and model.holds_multipliers() and model.reduce_all_finite(du):
            du = _rigid_response(model, u, du, lam + dlam, loads, solver)
    except RuntimeError:  # a singular tangent: no prediction, the step runs as it is
        return None
    if du is None or not model.reduce_all_finite(du):
        return None
    found = [s for g in groups if (s := g.activation(u, du)) is not None]
    first = model.reduce_min(min(found) if found else np.inf)
    return first if np.isfinite(first) else None


def _pending(model: Model) -> list[ElementGroup]:
    """The groups whose activation is pending. A group of a distributed model is each rank's share of a
    surface: pending on every rank, or not at all (a share without a plastic point on one rank while
    the set yields on another is not pending)."""
    held = model.reduce_max(np.array([0.0 if g.activation_pending() else 1.0 for g in model.groups]))
    return [g for g, h in zip(model.groups, held) if h == 0.0]


def pending(model: Model) -> bool:
    """True if a surface of the model has not yielded anywhere yet (its activation is still to locate)."""
    return bool(_pending(model))


def yielded(model: Model) -> bool:
    """True if a point of a surface (on any rank) has yielded in the step's trial state."""
    return model.reduce_any(any(g.yielded() for g in model.groups))


RIGID_UPDATES = 30  # the most multiplier updates of the rigid prediction


def _rigid_response(model: Model, u: np.ndarray, du: np.ndarray, lam: float, loads: Loads,
                    solver: LinearSolver) -> np.ndarray | None:
    """The response du of nested RP surfaces held rigid to the load increment: the penalty response du
    (multipliers held), then multiplier updates (``Model.augment``), each followed by a correction with
    the tangent (every point held constrained: the problem is linear, one Newton correction solves it;
    factorized anew each time, since a distributed model assembles into its last factor's matrix),
    until the multiplier rows are within round-off of the forces (1e-10);
    None if they are not after RIGID_UPDATES updates. The groups are left with the predicted
    multipliers, which their ``activation`` reads; the step's Newton starts afresh."""
    dofs_d = model.dirichlet
    f_ext = loads.forces(lam)
    scale = max(model.norm(f_ext, "free"), 1.0)
    model.constrain_all(True)
    try:
        for _ in range(RIGID_UPDATES):
            asm = model.assemble(u + du, u, f_ext)
            scale = max(scale, model.norm(asm.residual, "dirichlet"))
            if model.multiplier_gap() <= 1e-10 * scale:
                return du
            model.augment()
            asm = model.assemble(u + du, u, f_ext)
            r = asm.residual.copy()
            r[dofs_d] = 0.0
            du = du - solver.factorize(model.apply_dirichlet(asm.matrix)).solve(r)
        return None
    finally:
        model.constrain_all(False)
