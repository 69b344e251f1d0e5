"""Rigid-plastic CSE with its multipliers updated between Newton solves: the nested augmented
Lagrangian (Uzawa) form of paper Sect. 6.2, eq. 32-34 (Simo & Laursen 1992, for contact).

:class:`rockfrac.elements.cse_groups.CohesiveRP` solves the multipliers lambda with the displacements
(a saddle point). Here lambda is held fixed while Newton solves the displacements alone: each pair
then carries the law's augmented return of T^tr = lambda + r h (h its jump increment in the step), a
penalty surface of stiffness r shifted by lambda. Once that solve has converged, lambda := T (an Uzawa
update) and Newton goes on from there, until the multiplier rows of the saddle-point form,
w (T - lambda) = w r (h - Delta[[u^p]]), are within the Newton tolerance as well: the converged state
solves eq. (34), the surfaces' jumps are their plastic jumps (rigid below the yield surface), as with
the multipliers among the unknowns.

Why: no multiplier unknowns, so no saddle point, no statically indeterminate circulation round a
junction (no perturbed-Lagrangian term there, no redundant multiplier rows on supports), and a tangent
of the displacements alone, which a direct solver factorizes faster (3D RP joints: 0.63 of the saddle
point's time, benchmarks/README.md, "Nested multipliers"). The price: each update removes the elastic
jump (T - lambda) / r only down to the part the surroundings give back, a factor of about k / (k + r)
per update (k the bulk's stiffness seen by the pair, ~E / cell size), and much less while points
switch: with r >> k and a settled active set a few updates a step, else many (the paper's case: 2.7
times the saddle point's iterations). Where plastic pairs round a split node cannot flow (a kinked
boundary held by constrained pairs, or a ring whose other pairs are rigid), the rows do not close, and
the step fails after MAX_UPDATES (:mod:`rockfrac.solve.newton`) saying so.
"""

from __future__ import annotations

import numpy as np

from rockfrac.elements.base import Evaluation
from rockfrac.elements.cse_groups import CohesiveRP
from rockfrac.elements.interface_points import InterfacePoints
from rockfrac.laws.law3d import Law3D
from rockfrac.laws.traction_law import MODE_PLASTIC, TractionLaw


class CohesiveRPNested(CohesiveRP):
    """RP CSE whose multipliers (global-frame tractions [Pa], one per point) are held outside the
    unknowns and updated between Newton solves (module doc); ``[cohesive] multipliers = "nested"``."""

    n_extra = 0

    def __init__(self, points: InterfacePoints, law: TractionLaw | Law3D, augmentation: float, *,
                 name: str = "cohesive", viscosity: float = 0.0):
        super().__init__(points, law, augmentation, None, name=name, viscosity=viscosity)
        self.n_extra = 0
        self.lam = np.zeros((points.n, self.dim))  # the held multipliers, global frame [Pa]
        self._all_held = False  # constrain_all
        self._fresh = False  # lambda was just updated: the next evaluation holds the points inside at lambda

    def set_offset(self, offset: int) -> None:
        raise AssertionError("a nested RP surface has no extra unknowns to number")

    def extra_span(self) -> int:
        return 0

    def initial_unknowns(self, u0: np.ndarray) -> None:
        """No unknowns of its own; the multipliers start at the in-situ tractions (set_initial_stress)."""

    def redundant_extras(self, dirichlet: np.ndarray) -> np.ndarray:
        return np.zeros(0, dtype=np.int64)

    def begin_step(self) -> None:
        """The step's first multipliers: the committed tractions (lambda = T at convergence)."""
        super().begin_step()
        self.lam = self.points.from_local(self.state[:, self._t])
        self._fresh = False  # an update of the activation's prediction is not one of the step's

    def multipliers(self, u: np.ndarray) -> np.ndarray:
        """Global-frame multipliers (n_pts, dim) [Pa]: the held ones (u carries none)."""
        return self.lam

    def traction_increment(self, u: np.ndarray, du: np.ndarray) -> np.ndarray:
        """Local tractions' increment (n_pts, dim) [Pa] along du from the committed state while every
        point is constrained: lambda + r h, less the committed traction."""
        h = self.jumps(u + du) - self.jumps(u)
        return self.points.local(self.lam + self.aug * h) - self.state[:, self._t]

    def constrain_all(self, on: bool) -> None:
        """While on, every point is held constrained (T = lambda + r h, whatever its trial): the linear
        response of the surfaces before any point yields, which the activation's prediction follows
        (:func:`rockfrac.solve.events.activation_fraction`)."""
        self._all_held = on

    def evaluate(self, u: np.ndarray, u_n: np.ndarray) -> Evaluation:
        """The saddle-point form's evaluation with lambda held: its displacement rows and their block
        (the multiplier columns drop out; its multiplier rows, w (T - lambda), are the model's
        multiplier_gap)."""
        if self._all_held:
            self._pinned[:] = True
        ev = self._evaluate_fresh(u, u_n) if self._fresh and not self._all_held else super().evaluate(u, u_n)
        nd = 2 * self.dim
        return Evaluation(np.ascontiguousarray(ev.fe[:, :nd]), np.ascontiguousarray(ev.ke[:, :nd, :nd]), ok=ev.ok,
                          n_switched=ev.n_switched, message=ev.message, local_residual=ev.local_residual)

    def held_multipliers(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(lambda, T, w): the held multipliers, the last evaluation's tractions (global frame) [Pa]
        and the points' weights."""
        return self.lam, self.points.from_local(self.trial[:, self._t]), self.points.weight

    def _evaluate_fresh(self, u: np.ndarray, u_n: np.ndarray) -> Evaluation:
        """The first evaluation after an update, with every point that was not plastic in the last one
        and whose new lambda is inside its yield surface held constrained (T = lambda + r h), once.

        Right after lambda := T the trial lambda + r h counts the elastic jump h twice (it is already in
        lambda), up to r h outside: a rigid point would yield there, and a softening surface be put on
        its falling branch below its peak (the traction-loaded bar at 0.78 of its load, where it yields
        at 0.784). The correction from this evaluation closes those jumps; the iterations after it are
        the plain ones."""
        self._fresh = False
        at = self.trial.copy()  # the last evaluation's: its plastic points flow on, the others are held
        at[:, self._t] = self.points.local(self.lam)
        inside = (at[:, self.mode] != MODE_PLASTIC) & (self.law.yield_values(at) < -self.PIN_TOLERANCE * self.law.scale)
        kept = self._pinned.copy(), self._released.copy(), self._flips.copy()
        self._pinned |= inside
        ev = super().evaluate(u, u_n)
        self._pinned[:], self._released[:], self._flips[:] = kept  # the hold leaves no trace in the step
        return ev

    def hold_multipliers(self, lam: np.ndarray) -> None:
        self.lam = np.array(lam, dtype=float).reshape(self.points.n, self.dim)
        self._fresh = True
