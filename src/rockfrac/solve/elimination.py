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
    return _fewest(free, r, float(np.dot(r, r)))


def _strongest(r: np.ndarray) -> np.ndarray:
    """The positions of the MOST_UNKNOWNS largest |r|, largest first."""
    k = min(MOST_UNKNOWNS, r.size)
    top = np.argpartition(-np.abs(r), k - 1)[:k] if k < r.size else np.arange(r.size)
    return top[np.argsort(-np.abs(r[top]), kind="stable")]


def _fewest(dofs: np.ndarray, r: np.ndarray, total: float) -> np.ndarray | None:
    """Of ``dofs`` with residual entries ``r``, the fewest (at most MOST_UNKNOWNS, sorted) that carry
    SHARE of a residual whose squared norm is ``total``; None if more would be needed."""
    if not total > 0.0 or not r.size:
        return None
    top = _strongest(r)
    carried = np.cumsum(r[top] ** 2)
    enough = np.flatnonzero(carried >= SHARE ** 2 * total)
    if not enough.size:
        return None
    return np.sort(dofs[top[: enough[0] + 1]])


class _Unknowns:
    """The stalled unknowns as the model's vectors hold them: serially their dofs; on an MPI rank the
    whole model's numbers (alike on every rank), the local entries of those the rank holds, and which
    it owns. Their block of the tangent and their residual are the whole model's on every rank."""

    def __init__(self, model: Model, residual: np.ndarray):
        self.model = model
        self.dofs: np.ndarray | None
        if not model.distributed:
            self.dofs = stalled_unknowns(residual, model.free)
            self.local, self.held = self.dofs, None
            return
        owned = model.owned(residual)[model.free]  # each entry on its owner only
        top = _strongest(owned) if owned.size else np.zeros(0, dtype=np.int64)
        parts = model.allgather((model.global_dofs(model.free[top]), owned[top]))  # the global top is among these
        self.dofs = _fewest(np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts]),
                            model.dot(residual, residual))
        if self.dofs is None:
            return
        # their local entries, and which of them this rank holds (owned or ghost)
        self.local, self.held = model.held_dofs(self.dofs)

    def values(self, x: np.ndarray) -> np.ndarray:
        """x at the unknowns (the whole model's values: on a rank, each from its owner)."""
        if self.held is None:
            return x[self.local]
        assert self.dofs is not None
        out = np.zeros(self.dofs.shape[0])
        out[self.held] = self.model.owned(x)[self.local]
        return self.model.reduce_sum(out)

    def block(self, asm: Assembled) -> np.ndarray:
        """The tangent's block on the unknowns (dense; on a rank, the sum of every rank's elements')."""
        if self.held is None:
            return asm.matrix[self.local][:, self.local].toarray()
        assert self.dofs is not None and asm.own is not None
        n = self.dofs.shape[0]
        out = np.zeros((n, n))
        where = np.flatnonzero(self.held)
        out[np.ix_(where, where)] = asm.own[self.local][:, self.local].toarray()
        return self.model.reduce_sum(out)

    def moved(self, u: np.ndarray, step: np.ndarray) -> np.ndarray:
        """u with the unknowns moved by ``step`` (on a rank, at every local entry of them it holds)."""
        x = u.copy()
        x[self.local] += step if self.held is None else step[self.held]
        return x


def eliminate(model: Model, u: np.ndarray, u_n: np.ndarray, f_ext: np.ndarray,
              assembled: Assembled) -> Eliminated | None:
    """Solve the rows of the stalled unknowns for those unknowns, every other one held (a damped
    Newton on their block of the tangent, each trial the model's assembly at u_n and f_ext); None if
    the residual is not local or the local residual could not be lowered. On MPI ranks a collective
    call: the unknowns may lie on several ranks, and every rank takes the same steps."""
    stalled = _Unknowns(model, assembled.residual)
    if stalled.dofs is None:
        return None
    start, asm = u, assembled
    before = now = float(np.linalg.norm(stalled.values(asm.residual)))
    current = True  # the groups' trial state is that of (u, asm)
    for _ in range(ITERATIONS):
        block = stalled.block(asm)
        try:
            step = np.linalg.solve(block, -stalled.values(asm.residual))
        except np.linalg.LinAlgError:
            break
        alpha, found = 1.0, None
        for _ in range(HALVINGS + 1):
            x = stalled.moved(u, alpha * step)
            trial = model.assemble(x, u_n, f_ext)
            current = False
            if trial.ok and model.reduce_all_finite(trial.residual):
                norm = float(np.linalg.norm(stalled.values(trial.residual)))
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
    return Eliminated(u, asm, stalled.dofs, before, now)
