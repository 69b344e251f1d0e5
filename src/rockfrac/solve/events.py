"""Events located inside a load step: the first activation of a cohesive surface (its peak).

While a surface has not yielded anywhere, the response to a load increment from the committed state
is the linear one of the committed tangent; along it each point's traction moves on a straight line,
and the fraction of the increment at which the first point meets its yield surface is found by
bisection (:meth:`rockfrac.elements.base.ElementGroup.activation`). The stepping then ends the step
there, so the activation (the peak of a brittle crack) is a converged step rather than stepped over.
"""

from __future__ import annotations

import numpy as np

from rockfrac.model import Model
from rockfrac.solve.linear import LinearSolver
from rockfrac.solve.newton import Loads


def activation_fraction(model: Model, u: np.ndarray, lam: float, dlam: float, loads: Loads,
                        solver: LinearSolver) -> float | None:
    """The fraction of the load increment lam -> lam + dlam at which a pending surface first
    yields along the committed tangent's response, or None (none pending, or none yields)."""
    if not model.reduce_any(any(g.activation_pending() for g in model.groups)):
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
        du = solver.factorize(model.apply_dirichlet(a)).solve(rhs)
    except RuntimeError:  # a singular tangent: no prediction, the step runs as it is
        return None
    if not model.reduce_all_finite(du):
        return None
    found = [s for g in model.groups if (s := g.activation(u, du)) is not None]
    first = model.reduce_min(min(found) if found else np.inf)
    return first if np.isfinite(first) else None
