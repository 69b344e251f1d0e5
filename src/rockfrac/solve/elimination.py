"""Nonlinear elimination of a Newton iteration's few stalled unknowns (Lanzkron, Rose & Wilkes 1996;
Cai & Li 2011).

A load step of cohesive surfaces on every edge can stall with the whole residual at one or two
interface elements: their points sit where the traction law bends on a scale below the global
correction (the grains' EP: a jump of 1e-9 m moves a trial by 2000 Pa across a yield surface rounded
over 1400 Pa), so each global correction overshoots them, and Newton goes round a cycle with every
other unknown converged (benchmarks/README.md, "Why its steps fail"). Once the iteration has stalled,
the unknowns that carry the residual are solved for alone, by a damped Newton on their own rows with
every other unknown held, and the global iteration goes on from there. A local correction is kept if
it lowers the local residual by a quarter of its step's share (Armijo's test on the norm), else halved.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rockfrac.model import Assembled, Model

MOST_UNKNOWNS = 32  # the largest local problem: a few interface elements' node pairs
SHARE = 0.9  # the share of the residual's norm the local unknowns must carry
ITERATIONS = 20  # local Newton iterations
HALVINGS = 6  # halvings of a local correction that does not lower the local residual enough
DECREASE = 0.25  # a local correction alpha d is kept if it lowers the local residual by DECREASE alpha of it
REDUCTION = 1e-3  # the local residual's reduction that ends the local iteration
STALL = 0.5  # the iteration stalled: the residual is above this fraction of the least of the 5 before


@dataclass
class Eliminated:
    """A local solve: the new iterate and its assembly, the unknowns solved for, and the local
    residual's norm before and after [N/m]."""

    u: np.ndarray
    assembled: Assembled
    unknowns: np.ndarray
    before: float
    after: float


def stalled(residuals: list[float]) -> bool:
    """True if, from the 7th iterate on, the relative residual is not below half the least of the five
    before it (a converging Newton halves it at every iteration)."""
    return len(residuals) >= 7 and residuals[-1] > STALL * min(residuals[-6:-1])


def stalled_unknowns(residual: np.ndarray, free: np.ndarray) -> np.ndarray | None:
    """The fewest free dofs (at most MOST_UNKNOWNS) whose residual entries carry SHARE of its norm;
    None if more would be needed (the residual is not local)."""
    r = residual[free]
    total = float(np.dot(r, r))
    if not total > 0.0:
        return None
    k = min(MOST_UNKNOWNS, r.size)
    top = np.argpartition(-np.abs(r), k - 1)[:k] if k < r.size else np.arange(r.size)
    top = top[np.argsort(-np.abs(r[top]), kind="stable")]
    carried = np.cumsum(r[top] ** 2)
    enough = np.flatnonzero(carried >= SHARE ** 2 * total)
    if not enough.size:
        return None
    return np.sort(free[top[: enough[0] + 1]])


def eliminate(model: Model, u: np.ndarray, u_n: np.ndarray, f_ext: np.ndarray,
              assembled: Assembled) -> Eliminated | None:
    """Solve the rows of the stalled unknowns for those unknowns, every other one held (a damped
    Newton on their block of the tangent, each trial the model's assembly at u_n and f_ext); None if
    the residual is not local or the local residual could not be lowered."""
    if model.distributed:  # the unknowns would be on several ranks
        return None
    unknowns = stalled_unknowns(assembled.residual, model.free)
    if unknowns is None:
        return None
    start, asm = u, assembled
    before = now = float(np.linalg.norm(asm.residual[unknowns]))
    current = True  # the groups' trial state is that of (u, asm)
    for _ in range(ITERATIONS):
        block = asm.matrix[unknowns][:, unknowns].toarray()
        try:
            step = np.linalg.solve(block, -asm.residual[unknowns])
        except np.linalg.LinAlgError:
            break
        alpha, found = 1.0, None
        for _ in range(HALVINGS + 1):
            x = u.copy()
            x[unknowns] += alpha * step
            trial = model.assemble(x, u_n, f_ext)
            current = False
            if trial.ok and np.all(np.isfinite(trial.residual)):
                norm = float(np.linalg.norm(trial.residual[unknowns]))
                if norm <= (1.0 - DECREASE * alpha) * now:
                    found, current = (x, trial, norm), True
                    break
            alpha *= 0.5
        if found is None:
            break
        u, asm, now = found
        if now <= REDUCTION * before:
            break
    if not current:  # the last trial was refused: the groups' trial state back at the iterate kept
        asm = model.assemble(u, u_n, f_ext)
    if u is start:
        return None
    return Eliminated(u, asm, unknowns, before, now)
