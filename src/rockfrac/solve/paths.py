"""Path measures of indirect control: the scalar g(u, lam) a step prescribes the increment of.

A stage under indirect control solves for its load factor lam with one more equation,
g(u, lam) = g(u_n, lam_n) + increment, built afresh at every step from the committed state
(:class:`Committed`). The measures here: a crack's mean jump or an opening between two points
(``crack_path``, given by the case), the arc length (``arc_length_path``) and the energy released
(``energy_path``, Gutierrez 2004).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from rockfrac.solve.newton import Loads, Measure


@dataclass(frozen=True)
class Committed:
    """The committed state a step's measure is built on."""

    u: np.ndarray
    u_before: np.ndarray | None  # u one converged step earlier in the stage (None at its start)
    lam: float
    loads: Loads  # the stage's loads: d(lam), f(lam)
    u_ref: np.ndarray  # the program's initial state (displacements and forces at t = 0)
    f_ref: np.ndarray


@dataclass(frozen=True)
class Constraint:
    """g(u, lam) = measure(u)[0] + lam_coeff lam, linear in lam; dg/du = measure(u)[1]."""

    measure: Measure
    lam_coeff: float = 0.0

    def value(self, u: np.ndarray, lam: float) -> float:
        return self.measure(u)[0] + self.lam_coeff * lam


@dataclass(frozen=True)
class PathSpec:
    """Indirect control of a stage once ``active()`` is true.

    constraint(committed): g for the next step; None if it cannot be defined yet (a load-controlled
    step then). increment: nominal increment of g per step; None: the change of g over a nominal
    load step, taken from the stage's first step.
    """

    constraint: Callable[[Committed], Constraint | None]
    increment: float | None
    active: Callable[[], bool]  # evaluated on the committed state
    max_steps: int
    name: str = "crack jump"
    rigid_ok: bool = False  # a step where g cannot move (held shut by rigid surfaces) is a load step


def crack_path(measure: Callable[[], Measure | None], increment: float | None, active: Callable[[], bool],
               max_steps: int, name: str = "crack jump", rigid_ok: bool = False) -> PathSpec:
    """A path on a measure of u alone, rebuilt each step (crack jumps along their current flow
    directions, an opening between two points)."""

    def constraint(c: Committed) -> Constraint | None:
        m = measure()
        return None if m is None else Constraint(m)

    return PathSpec(constraint, increment, active, max_steps, name, rigid_ok)


class Ranks(Protocol):
    """The reductions of a model distributed over MPI ranks (rockfrac.model.Model)."""

    distributed: bool

    def owned(self, x: np.ndarray) -> np.ndarray: ...

    def reduce_sum(self, value: Any) -> Any: ...


def _linear(grad: np.ndarray, const: float = 0.0, ranks: Ranks | None = None) -> Measure:
    """g(u) = grad . u + const; on several ranks grad is this rank's part (its owned dofs) and the
    value sums the ranks' parts."""
    if ranks is None or not ranks.distributed:
        return lambda v: (float(grad @ v) + const, grad)
    return lambda v: (ranks.reduce_sum(float(grad @ v)) + const, grad)


def _dot(x: np.ndarray, y: np.ndarray, ranks: Ranks | None) -> float:
    """x . y of two vectors on the rank's local dofs, each dof once over the ranks (x owned-restricted)."""
    return float(x @ y) if ranks is None or not ranks.distributed else ranks.reduce_sum(float(ranks.owned(x) @ y))


def arc_length_path(n_displacements: int, increment: float | None, max_steps: int,
                    ranks: Ranks | None = None, n_total: int | None = None) -> PathSpec:
    """The linearised arc length over the first ``n_displacements`` dofs (the nodal displacements):
    g(u) = t . u / sqrt(n), t the unit direction of the last converged increment (Riks' normal
    plane, updated every step), so that an increment of g is the root-mean-square nodal
    displacement along the path [m]. ``ranks``: a distributed model (t over each rank's owned dofs,
    n_total the displacement dofs of every rank; default n_displacements)."""
    scale = 1.0 / np.sqrt(n_total or n_displacements)
    distributed = ranks is not None and ranks.distributed

    def constraint(c: Committed) -> Constraint | None:
        if c.u_before is None:
            return None
        t = np.zeros(c.u.shape[0])
        t[:n_displacements] = c.u[:n_displacements] - c.u_before[:n_displacements]
        if distributed:
            assert ranks is not None
            t = ranks.owned(t)
            norm = math.sqrt(ranks.reduce_sum(float(t @ t)))
        else:
            norm = float(np.linalg.norm(t))
        if norm == 0.0:
            return None
        t *= scale / norm
        return Constraint(_linear(t, 0.0, ranks))

    return PathSpec(constraint, increment, lambda: True, max_steps, "arc length")


def energy_path(n_displacements: int, thickness: float, increment: float, active: Callable[[], bool],
                max_steps: int, ranks: Ranks | None = None) -> PathSpec:
    """The energy released over a step (Gutierrez 2004, measured from the initial state):
    g(u, lam) = [(f_n - f_0) . (u - u_0) - (f(lam) - f_0) . (u_n - u_0)] / (2 thickness) [J per unit
    thickness in 2D], f the external forces. It is the dissipation of a step for a body that
    unloads to its initial state along the secant (damage); for the plasticity laws here it is the
    energy an unloading would not give back, and it grows through softening. The supports must
    not move (their reactions do no work): the stage is driven by forces. ``ranks``: a distributed
    model (its dot products over each rank's owned dofs)."""

    def constraint(c: Committed) -> Constraint:
        n = n_displacements
        f_n = c.loads.forces(c.lam)
        a = np.zeros(c.u.shape[0])
        a[:n] = (f_n[:n] - c.f_ref[:n]) / (2.0 * thickness)
        back = c.u[:n] - c.u_ref[:n]
        if ranks is not None and ranks.distributed:
            a = ranks.owned(a)
            const = -_dot(a[:n], c.u_ref[:n], ranks) - _dot(c.loads.f0[:n] - c.f_ref[:n], back, ranks) / (
                2.0 * thickness)
            lam_coeff = -_dot(c.loads.df[:n], back, ranks) / (2.0 * thickness)
            return Constraint(_linear(a, const, ranks), lam_coeff)
        const = -float(a[:n] @ c.u_ref[:n]) - float((c.loads.f0[:n] - c.f_ref[:n]) @ back) / (2.0 * thickness)
        lam_coeff = -float(c.loads.df[:n] @ back) / (2.0 * thickness)
        return Constraint(lambda v: (float(a @ v) + const, a), lam_coeff)

    return PathSpec(constraint, increment, active, max_steps, "energy released")
