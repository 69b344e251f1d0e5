"""Newton-Raphson for one load step with the consistent tangent.

Convergence needs both the residual norm (relative to the external and reaction forces) and the
energy norm |du_(k-1) . r_k| (the work of the current residual on the last correction, relative
to that of the first iteration) below tolerance, and no change of state
(constrained <-> plastic) in the last iteration. Every iteration is logged.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from rockfrac.model import Model
from rockfrac.solve.linear import LinearSolver


@dataclass(frozen=True)
class NewtonOptions:
    max_iterations: int = 25
    tol_residual: float = 1e-8
    tol_energy: float = 1e-10
    force_scale: float = 1.0  # floor of the residual reference [N/m]


@dataclass
class NewtonResult:
    converged: bool
    u: np.ndarray
    iterations: int
    residuals: list[float] = field(default_factory=list)  # relative residual per iteration
    energies: list[float] = field(default_factory=list)  # relative energy per iteration
    message: str = ""
    f_int: np.ndarray | None = None


def newton_step(
    model: Model,
    u_n: np.ndarray,
    u_target_dirichlet: np.ndarray,
    f_ext: np.ndarray,
    solver: LinearSolver,
    options: NewtonOptions,
) -> NewtonResult:
    """Solve R(u) = f_int(u) - f_ext = 0 with u = u_target on the Dirichlet dofs, from u_n."""
    dofs_d = model.dirichlet
    free = model.free
    u = u_n.copy()
    model.begin_step()
    result = NewtonResult(False, u, 0)
    energy0 = None
    last_du = None
    for it in range(options.max_iterations + 1):
        asm = model.assemble(u, u_n, f_ext)
        if not asm.ok:
            result.message = f"iteration {it}: {asm.message}"
            return result
        r = asm.residual
        if not np.all(np.isfinite(r)):
            result.message = f"iteration {it}: non-finite residual"
            return result
        ref = max(np.linalg.norm(f_ext[free]), np.linalg.norm(r[dofs_d]), options.force_scale)
        rel = float(np.linalg.norm(r[free]) / ref)
        result.residuals.append(rel)
        if it > 0:
            work = abs(float(last_du[free] @ r[free]))
            rel_e = work / energy0 if energy0 else 0.0
            result.energies.append(rel_e)
            if rel <= options.tol_residual and rel_e <= options.tol_energy and asm.n_switched == 0:
                result.converged = True
                result.iterations = it
                result.f_int = asm.f_int
                return result
        if it == options.max_iterations:
            break
        a = asm.matrix
        rhs = -r
        if it == 0:
            # the prescribed increment enters through the tangent (consistent predictor)
            step = np.zeros_like(u)
            step[dofs_d] = u_target_dirichlet - u_n[dofs_d]
            rhs = rhs - a @ step
        rhs[dofs_d] = (u_target_dirichlet - u_n[dofs_d]) if it == 0 else 0.0
        du = solver.solve(model.apply_dirichlet(a), rhs)
        if not np.all(np.isfinite(du)):
            result.message = f"iteration {it}: singular or ill-conditioned tangent"
            return result
        if energy0 is None or energy0 == 0.0:
            energy0 = abs(float(du[free] @ rhs[free]))
        last_du = du
        u += du
        result.iterations = it + 1
    result.message = f"no convergence in {options.max_iterations} iterations (residual {rel:.2e})"
    return result
