"""Newton-Raphson for one load step with the consistent tangent, under load or path control.

Loads depend on a load factor lam: prescribed values d(lam) = d0 + lam dd on the Dirichlet dofs
and external forces f(lam) = f0 + lam df. Under load control lam is given; under path control
(indirect displacement control) lam is an extra unknown fixed by a scalar constraint
g(u) = target, solved with the bordered scheme: two right-hand sides on one factorization.
Where g does not respond to lam (a rigid-plastic surface still fully constrained, or yielding only at
pairs that cannot open, held shut on a loop round a node), the iteration takes a load-controlled
predictor increment instead (the load factor lam_n + predictor); with ``rigid_ok`` the step then
converges as a load step of that increment.

Convergence needs the residual norm (relative to the external and reaction forces) and the energy
norm |du_(k-1) . r_k| (the work of the current residual on the last correction, relative to that
of the largest so far) below tolerance (or, at an iterate that switched points, the residual at
round-off, an equilibrium within tolerance the iteration came back to by switching after leaving
it, or one within tolerance after points switched in most of the last iterations: see newton_step),
element-level equations of condensed unknowns (the embedded jumps) met to the residual tolerance,
and, under path control, the constraint met.
With nested RP multipliers (:mod:`rockfrac.elements.cse_nested`) the multiplier rows, held outside
the unknowns, must meet the residual tolerance too: an iterate converged with them held (or within a
tenth of their residual, switching nothing) updates them (``Model.augment``) and the iteration goes
on from there, each update granting the solve after it max_iterations, at most MAX_UPDATES a step.
A correction that raises the residual is halved (line search) from the third iteration on.
With ``eliminate`` (``[solver] elimination``), an iteration that has stalled with its residual on a
few unknowns solves those alone first (:mod:`rockfrac.solve.elimination`).
Every iteration is logged, with the number of points whose state its iterate switched (an active-set
change: a cohesive point between elastic or constrained and plastic, an embedded crack between
sticking and sliding), which the step control reads (:mod:`rockfrac.solve.stepping`).

The norms and dot products of the convergence test are the model's (:meth:`rockfrac.model.Model.dot`):
a serial compiled loop, or sums over the ranks of a distributed model.
"""

from __future__ import annotations

import itertools
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from rockfrac.model import Model
from rockfrac.solve.elimination import eliminate, stalled
from rockfrac.solve.linear import LinearSolver


@dataclass(frozen=True)
class NewtonOptions:
    max_iterations: int = 25
    tol_residual: float = 1e-8
    tol_energy: float = 1e-10
    force_scale: float = 1.0  # floor of the residual reference [N/m]
    line_search: int = 3  # most halvings of a correction that raises the residual (0: plain Newton)
    eliminate: bool = False  # a stalled iteration solves the few unknowns carrying its residual alone (elimination)
    should_stop: Callable[[], bool] | None = None  # looked at before every iteration (a stop request)


@dataclass(frozen=True)
class Loads:
    """Load path of a stage: d(lam) = d0 + lam dd (Dirichlet values), f(lam) = f0 + lam df."""

    d0: np.ndarray
    dd: np.ndarray
    f0: np.ndarray
    df: np.ndarray

    def dirichlet(self, lam: float) -> np.ndarray:
        return self.d0 + lam * self.dd

    def forces(self, lam: float) -> np.ndarray:
        return self.f0 + lam * self.df


Measure = Callable[[np.ndarray], tuple[float, np.ndarray]]  # u -> (g, dg/du dense over the dofs)


@dataclass(frozen=True)
class PathControl:
    """Scalar constraint g(u, lam) = measure(u)[0] + lam_coeff lam = target."""

    measure: Measure
    target: float
    tolerance: float  # absolute tolerance on g - target
    predictor: float = 0.0  # load-factor increment of an iteration where g does not respond to lam
    rigid_ok: bool = False  # True: a step in which g cannot respond (rigid) converges as a load step
    lam_coeff: float = 0.0  # dg/dlam


@dataclass
class NewtonResult:
    converged: bool
    u: np.ndarray
    lam: float
    iterations: int
    residuals: list[float] = field(default_factory=list)  # relative residual per iteration
    energies: list[float] = field(default_factory=list)  # relative energy per iteration
    message: str = ""
    f_int: np.ndarray | None = None
    time_assembly: float = 0.0  # seconds in residual/tangent assembly (constitutive updates included)
    time_solve: float = 0.0  # seconds in factorization and triangular solves
    interrupted: bool = False  # ended by options.should_stop (not converged, nothing wrong)
    switched: list[int] = field(default_factory=list)  # points whose state switched at each iterate (active set)
    eliminated: list[int] = field(default_factory=list)  # iterations that were a local solve (elimination)
    eliminated_unknowns: list[int] = field(default_factory=list)  # the unknowns each of them solved for
    augmented: list[int] = field(default_factory=list)  # iterations whose iterate updated nested multipliers
    gaps: list[float] = field(default_factory=list)  # the relative multiplier gap each of those updates closed

    @property
    def switching_iterations(self) -> int:
        """The iterations whose iterate switched a point's state (an active-set change)."""
        return sum(1 for n in self.switched[1:] if n)


# g does not respond to the load (rigid) where dg/dlam is below RIGID_SLOPE |grad g| |du/dlam| (the
# displacements' part: grad g has no other), or where meeting the target would move the load factor by
# more than MAX_PATH_LOAD, a whole stage, in one step: the leak through the junction term of an RP pair
# held shut on a loop (~1e-12 relative; an opening mechanism gives 1e-6 and more)
RIGID_SLOPE = 1e-12
MAX_PATH_LOAD = 1.0

MAX_UPDATES = 30  # the most updates of nested multipliers in a step (each followed by a Newton solve)
INEXACT = 0.1  # nested multipliers are updated once the residual is this far below their rows' (inexact Uzawa)

ROUNDOFF = 1e-4  # at an iterate that switched points, a residual this far below its tolerance converges

# relative: residuals this close one period apart are the same iterate again. The grains' RP 3-cycles
# repeat their residuals to the 4 digits logged, but their energies differ in the 4th (6.915e-5 and
# 6.916e-5): the iterates come back to within round-off of their own switching, not bit for bit
CYCLE_TOL = 1e-3
CYCLE_PERIODS = (2, 3, 4)  # the periods looked for, shortest first
_STATES = {2: "two", 3: "three", 4: "four"}


def _returned(residuals: list[float], switched: list[int], tol: float) -> bool:
    """True if the last iterate is an equilibrium within ``tol`` that the iteration came back to: it
    and the one two before it switched points and are within tol, the one between them is not (a
    point on its yield surface flipped out of the equilibrium and back; the next correction flips it
    out again, so the energy norm, weighing the residual by the switching correction, never settles)."""
    if len(residuals) < 4:
        return False
    r, s = residuals[-3:], switched[-3:]
    return r[2] <= tol and r[0] <= tol and r[1] > tol and s[2] > 0 and s[0] > 0


def _cycle_period(residuals: list[float]) -> int:
    """p if the last 2p + 1 residuals repeat with period p (r_k = r_(k-p) over two periods, to CYCLE_TOL)
    for p in CYCLE_PERIODS, the shortest such, and the period's residuals are not all alike (a stall);
    else 0. The iteration is deterministic, so iterates that have come back to where they were twice
    will go on cycling (active sets flipping round a point on its yield surface)."""

    def same(a: float, b: float) -> bool:
        return abs(a - b) <= CYCLE_TOL * max(abs(a), abs(b))

    for p in CYCLE_PERIODS:
        if len(residuals) < 2 * p + 1:
            break
        r = residuals[-(2 * p + 1):]
        if all(same(r[i], r[i + p]) for i in range(p + 1)) and not all(same(r[0], r[i]) for i in range(1, p)):
            return p
    return 0


def _cycling(residuals: list[float]) -> bool:
    """True if the last residuals are a cycle of period 2 to 4 repeated twice over (:func:`_cycle_period`)."""
    return _cycle_period(residuals) > 0


UNSETTLED = 8  # the last iterations looked at for an active set that does not settle


def points(n: int) -> str:
    """'1 point', 'n points'."""
    return f"{n} point" + ("" if n == 1 else "s")


def unsettled(switched: list[int]) -> str:
    """A failure's note when points switched in most (at least 60 %) of its last UNSETTLED
    iterations, and at least 4 (else ""): the iteration did not settle on an active set, as against
    diverging on a fixed one. A point flipping back and forth may skip iterations."""
    tail = switched[1:][-UNSETTLED:]
    hits = [n for n in tail if n]
    if len(tail) < 4 or len(hits) < 0.6 * len(tail):
        return ""
    lo, hi = min(hits), max(hits)
    count = f"{lo}" if lo == hi else f"{lo}-{hi}"
    return (f"; points switched in {len(hits)} of the last {len(tail)} iterations ({count} at a time): "
            "the active set does not settle")


def newton_step(
    model: Model,
    u_n: np.ndarray,
    lam_n: float,
    lam: float,
    loads: Loads,
    solver: LinearSolver,
    options: NewtonOptions,
    control: PathControl | None = None,
) -> NewtonResult:
    """Solve f_int(u) = f(lam), u_D = d(lam) from the converged (u_n, lam_n).

    Load control: ``lam`` is the target. Path control: ``lam`` is the initial guess and the
    result's lam satisfies ``control``.
    """
    dofs_d = model.dirichlet
    u = u_n.copy()
    if control is None:
        u_lam = lam
    else:
        u_lam = lam_n  # start from the converged state; lam becomes an unknown
    model.begin_step()
    solver.begin_step()  # a backend may refresh per-step data (PARDISO's analysis)
    result = NewtonResult(False, u, u_lam, 0)
    energy0 = None
    last_du = None
    rel = np.inf
    pending = None  # the assembly at u made by the line search
    rigid = False  # the last correction could not move g (it pushed the load by control.predictor)
    tried = -3  # the iteration of the last elimination tried
    nested = model.holds_multipliers()  # multipliers updated between solves (rockfrac.elements.cse_nested)

    def reference(asm, f_ext) -> float:
        return max(model.norm(f_ext, "free"), model.norm(asm.residual, "dirichlet"), options.force_scale)

    def relative(asm, f_ext) -> float:
        return model.norm(asm.residual, "free") / reference(asm, f_ext)

    limit = options.max_iterations  # the last iteration (each multiplier update grants a solve its own)
    for it in itertools.count():
        if options.should_stop is not None and options.should_stop():
            result.interrupted = True
            result.message = f"iteration {it}: stop requested"
            return result
        f_ext = loads.forces(u_lam)
        if pending is None:
            t0 = time.perf_counter()
            asm = model.assemble(u, u_n, f_ext)
            result.time_assembly += time.perf_counter() - t0
        else:
            asm, pending = pending, None
        if not asm.ok:
            result.message = f"iteration {it}: {asm.message}"
            return result
        result.switched.append(asm.n_switched)
        r = asm.residual
        if not model.reduce_all_finite(r):
            result.message = f"iteration {it}: non-finite residual"
            return result
        rel = relative(asm, f_ext)
        result.residuals.append(rel)
        mismatch = loads.dirichlet(u_lam) - u[dofs_d]
        g_ok = True
        if control is not None:
            g, grad = control.measure(u)
            if control.lam_coeff:
                g += control.lam_coeff * u_lam
            g_ok = abs(g - control.target) <= control.tolerance or (control.rigid_ok and rigid)
        if (it == 0 and control is None and rel <= options.tol_residual and asm.local_residual <= options.tol_residual
                and not model.reduce_any(bool(np.any(mismatch)))  # on any rank's prescribed dofs
                and (not nested or model.multiplier_gap() <= options.tol_residual * reference(asm, f_ext))):
            # the loads did not change over the step (a held stage): the start is the equilibrium; a
            # Newton correction would be round-off, whose energy norm relative to itself never converges
            result.converged = True
            result.f_int = asm.f_int
            result.u, result.lam = u, u_lam
            return result
        if it > 0:
            assert last_du is not None  # set by every iteration before this one
            rel_e = abs(model.dot(last_du, r)) / energy0 if energy0 else 0.0
            result.energies.append(rel_e)
            # a rigid load step under an opening control is linear from an equilibrium: the energy of
            # its (round-off) residual relative to round-off says nothing
            held = control is not None and control.rigid_ok and rigid
            # a state switch in this iterate (constrained <-> plastic) is part of the residual just
            # computed (multiplier rows included), so a small residual is an equilibrium of its active
            # set, whatever the energy norm says: that norm weighs the residual by the switching
            # correction. Such an iterate converges with its residual at round-off (ROUNDOFF x the
            # tolerance), within tolerance once the iteration has come back to it (_returned), or
            # within tolerance once the active set has not settled (points switched in most of the
            # last iterations, ``unsettled``): dozens of points on their yield surfaces with no flow
            # flip at every iterate there, and the next equilibrium within tolerance is the answer
            # (the small grains' RP refused an iterate at 2.4e-9 with 51 points switching)
            settled = (rel_e <= options.tol_energy or held
                       or (asm.n_switched > 0 and rel <= ROUNDOFF * options.tol_residual)
                       or _returned(result.residuals, result.switched, options.tol_residual)
                       or (asm.n_switched > 0 and bool(unsettled(result.switched))))
            held_ok = g_ok and asm.local_residual <= options.tol_residual
            gap = model.multiplier_gap() / reference(asm, f_ext) if nested and held_ok else 0.0
            if rel <= options.tol_residual and settled and held_ok and gap <= options.tol_residual:
                result.converged = True
                result.iterations = it
                result.f_int = asm.f_int
                result.u, result.lam = u, u_lam
                return result
            if gap > options.tol_residual and ((rel <= options.tol_residual and settled)
                                               or (rel <= INEXACT * gap and not asm.n_switched)):
                if len(result.augmented) < MAX_UPDATES:
                    # nested multipliers: converged with lambda held (or nearly, next to the multiplier
                    # rows' residual), not yet T = lambda; lambda := T and Newton goes on from this u
                    # (an iteration without a solve), with max_iterations for its solve at the new lambda
                    model.augment()
                    limit = it + options.max_iterations
                    result.augmented.append(it)
                    result.gaps.append(gap)
                    last_du = np.zeros_like(u)
                    result.iterations = it + 1
                    continue
                result.message = (f"iteration {it}: the nested multipliers' rows are at {gap:.2e} after "
                                  f"{MAX_UPDATES} updates (lambda := T does not converge)")
                result.u, result.lam = u, u_lam
                return result
        if it >= limit:
            break
        if (options.eliminate and (stalled(result.residuals) or _cycle_period(result.residuals))
                and it - tried >= 3):  # not again before its effect shows (then a cycle ends the step)
            tried = it
            local = eliminate(model, u, u_n, f_ext, asm)
            if local is not None:
                result.eliminated.append(it)
                result.eliminated_unknowns.append(int(local.unknowns.size))
                last_du = local.u - u
                u, pending = local.u, local.assembled
                result.iterations = it + 1
                continue
        if period := _cycle_period(result.residuals):
            states = ("between " if period == 2 else "through ") + _STATES[period]
            values = ", ".join(f"{v:.3e}" for v in result.residuals[-period:])
            result.message = (f"iteration {it}: the iterates cycle {states} states (relative residuals "
                              f"{values} twice over): more iterations cannot converge; e.g. a point "
                              "flipping between its elastic and plastic states" + unsettled(result.switched))
            result.u, result.lam = u, u_lam
            return result
        a = asm.matrix
        lift = np.zeros_like(u)
        lift[dofs_d] = mismatch
        rhs = -r - a @ lift  # prescribed increments enter through the tangent
        rhs[dofs_d] = mismatch
        if control is not None:
            lift[dofs_d] = loads.dd
            rhs_b = loads.df - a @ lift
            rhs_b[dofs_d] = loads.dd
        t0 = time.perf_counter()
        try:
            lu = solver.factorize(model.apply_dirichlet(a))
            du = lu.solve(rhs)
            if control is not None:
                du_b = lu.solve(rhs_b)
                slope = model.gradient_dot(grad, du_b) + control.lam_coeff
                rigid = not abs(slope) > RIGID_SLOPE * model.gradient_norm(grad) * model.norm(du_b, "u")
                if not rigid:
                    dlam = (control.target - g - model.gradient_dot(grad, du)) / slope
                    rigid = abs(u_lam + dlam - lam_n) > MAX_PATH_LOAD
                if rigid:  # g cannot move (surfaces hold it shut): the step is a load step of the predictor
                    dlam = lam_n + control.predictor - u_lam
                du = du + dlam * du_b
                u_lam += dlam
            del lu  # freed before the next tangent is assembled and factorized: one factor alive at a time
        except RuntimeError as err:  # exactly singular factor
            result.message = f"iteration {it}: singular tangent ({err})"
            return result
        finally:
            result.time_solve += time.perf_counter() - t0
        if not model.reduce_all_finite(du):
            result.message = f"iteration {it}: singular or ill-conditioned tangent"
            return result
        energy0 = max(energy0 or 0.0, abs(model.dot(du, rhs)))  # largest so far
        if it >= 2 and options.line_search:
            # line search: the full correction is assembled (and reused next iteration); halved
            # while it raises the residual (breaks the flip-flop of a point on its yield surface)
            lam_from = u_lam - (dlam if control is not None else 0.0)
            alpha = 1.0
            for halving in range(options.line_search + 1):
                u_try = u + alpha * du
                lam_try = lam_from + alpha * (dlam if control is not None else 0.0)
                u_try[dofs_d] = loads.dirichlet(lam_try)
                f_try = loads.forces(lam_try)
                t0 = time.perf_counter()
                trial = model.assemble(u_try, u_n, f_try)
                result.time_assembly += time.perf_counter() - t0
                ok = trial.ok and model.reduce_all_finite(trial.residual)
                if ok and (relative(trial, f_try) <= rel or halving == options.line_search):
                    break
                alpha *= 0.5
            pending = trial
            last_du = alpha * du
            u, u_lam = u_try, lam_try
        else:
            last_du = du
            u += du
            u[dofs_d] = loads.dirichlet(u_lam)  # exact, no drift from summed increments
        result.iterations = it + 1
    updates = len(result.augmented)
    result.message = (f"no convergence in {options.max_iterations} iterations (residual {rel:.2e})"
                      + (f" since update {updates} of the nested multipliers" if updates else "")
                      + unsettled(result.switched))
    result.u, result.lam = u, u_lam
    return result
