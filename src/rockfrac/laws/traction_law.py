"""The contract of a cohesive traction law (a plug-in): its parameters, its state layout and its
compiled point updates, in one module.

A law module defines a subclass of :class:`TractionLaw` and is registered by one line in
:mod:`rockfrac.laws.registry`; the cohesive element groups, the case schema ([cohesive] law = ...),
the point output, ``rockfrac drive`` and the CLI take it from there. Local frame (t, n), tension
positive, tractions in Pa, jumps in m.

State: every law's state vector (n_state,) starts with the common slots T_t, T_n (tractions),
jump_p_t, jump_p_n (plastic jump) and then holds its own (``state_names``); ``mode_slot`` says
where the law keeps 0 (elastic/constrained) or 1 (plastic).

Kernels (compiled; the subclass names them as its ``ep_kernel`` and ``rp_kernel``, which the
groups call through :meth:`TractionLaw.ep_points` / :meth:`TractionLaw.rp_points` with the law's
parameter vector p):

- ``ep_points(frame, weight, djump, s_old, d_old, p, s_new, d_new, fe, ke, status)``: the penalty
  form (Sect. 6.1) at every point, blocks (n, 4), (n, 4, 4);
- ``rp_points(frame, weight, djump, lam, aug, eps, pinned, s_old, d_old, mode_prev, p, s_new, d_new,
  fe, ke, status, switched)``: the rigid-plastic form with augmented multipliers (Sect. 6.2), blocks
  (n, 6), (n, 6, 6) (see :func:`rockfrac.fem.interface.multiplier_rows`);
- ``ep_rescue_points(index, frame, weight, djump, s_old, p, s_new, d_new, fe, ke, status)``
  (``rescue_kernel``, optional): the points of ``ep_points`` whose return failed, solved another way
  (called only where one failed, so compiled only by a run that needs it);
- ``rp_rescue_points(index, frame, weight, djump, lam, aug, eps, s_old, mode_prev, p, s_new, d_new,
  fe, ke, status, switched)`` (``rp_rescue_kernel``, optional): the same for ``rp_points``;
- ``point_update(du, s_old, p, s_new, D)``: one EP update of one point (the material-point driver);
- ``trial_return(tr_t, tr_n, ct, cn, s_old, p, s_new, D) -> status`` (``trial_kernel``): the return
  from the trial traction (tr_t, tr_n) [Pa] with K = diag(1/ct, 1/cn), T_old = s_old's traction,
  D = dT/d(du) [Pa/m], never raising (< 0 on failure): the 2D kernel that
  :mod:`rockfrac.laws.traction3d` lifts to 3D, isotropic in the interface plane.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import Any, ClassVar

import numpy as np

from rockfrac.compiled import inner
from rockfrac.values import Section

S_TT, S_TN, S_UPT, S_UPN = 0, 1, 2, 3  # the common state slots
COMMON_STATE = ("T_t", "T_n", "jump_p_t", "jump_p_n")
MODE_PLASTIC = 1.0
SEPARATED = 1e-2  # a point left with less than this fraction of its virgin tensile strength is separated
# by default ([output] separated_fraction; the bilinear law reaches zero at delta_c, the paper's
# hyperbolic softening only tends to it)


@inner
def keep_committed(s_old, d_old, s_new, d_new, dgamma_slot):
    """Start of a step at a committed plastic point (no jump increment yet): same traction, the
    committed tangent, so Newton's first iteration predicts continued flow (the laws' point loops)."""
    for k in range(s_old.shape[0]):  # loops, not slice copies: no shape-error path to compile (~2 s)
        s_new[k] = s_old[k]
    s_new[dgamma_slot] = 0.0
    for i in range(d_old.shape[0]):
        for j in range(d_old.shape[1]):
            d_new[i, j] = d_old[i, j]


@inner
def hold_constrained(s_old, s_new, d_new, t_t, t_n, aug, dgamma_slot, mode_slot):
    """The constrained branch of the RP form (paper eq. 33) for a point held there (active-set
    pinning): T = lambda + r h given as (t_t, t_n), D = r I."""
    for k in range(s_old.shape[0]):
        s_new[k] = s_old[k]
    s_new[S_TT] = t_t
    s_new[S_TN] = t_n
    s_new[dgamma_slot] = 0.0
    s_new[mode_slot] = 0.0
    d_new[:, :] = 0.0
    d_new[0, 0] = aug
    d_new[1, 1] = aug


class TractionLaw(ABC):
    """A traction law with its parameters: EP form (penalties kn, kt) or RP form (both None)."""

    name: ClassVar[str]  # the value of [cohesive] law
    summary: ClassVar[str]  # one line for the docs and the CLI
    Parameters: ClassVar[type[Section]]  # the law's own keys of [cohesive] (pydantic model)
    state_names: ClassVar[tuple[str, ...]]  # the whole state vector, COMMON_STATE first
    mode_slot: ClassVar[int]
    dgamma_slot: ClassVar[int]  # where the state keeps the last update's plastic multiplier increment
    record_names: ClassVar[tuple[str, ...]]  # the law's per-point output quantities (strengths...)
    tensile_record: ClassVar[str]  # the record that is the point's tensile strength [Pa] (0: separated)
    ep_kernel: ClassVar[Any]  # the compiled ep_points(..., p, ...) of the module docstring
    rescue_kernel: ClassVar[Any] = None  # ep_rescue_points(index, frame, weight, djump, s_old, p, s_new, d_new,
    # fe, ke, status): the EP points whose return failed, solved another way (None: the law has none)
    rp_kernel: ClassVar[Any]  # the compiled rp_points(..., p, ...)
    rp_rescue_kernel: ClassVar[Any] = None  # rp_rescue_points(index, ..., p, ...): the RP points whose return
    # failed, solved another way (None: the law has none)
    trial_kernel: ClassVar[Any]  # the compiled trial_return(tr_t, tr_n, ct, cn, s_old, p, s_new, D) (3D)

    def __init__(self, params: Any, kn: float | None = None, kt: float | None = None):
        self.params = params
        self.kn, self.kt = kn, kt
        self.p = self.vector()

    @property
    def n_state(self) -> int:
        return len(self.state_names)

    @property
    def rigid(self) -> bool:
        """The rigid-plastic form (no penalty stiffness)."""
        return self.kn is None or self.kt is None

    @property
    def scale(self) -> float:
        """A traction scale of the law [Pa] (its peak strength), for tolerances."""
        return 1.0

    # -- what each law provides ----------------------------------------------------------------
    @abstractmethod
    def vector(self) -> np.ndarray:
        """The flat parameter vector the kernels read."""

    def ep_points(self, frame, weight, djump, s_old, d_old, s_new, d_new, fe, ke, status) -> None:
        """The EP form at every point (see the module docstring), with this law's parameters."""
        type(self).ep_kernel(frame, weight, djump, s_old, d_old, self.p, s_new, d_new, fe, ke, status)
        rescue = type(self).rescue_kernel
        if rescue is not None and status.min(initial=0) < 0:  # compiled when a run first needs it
            rescue(np.flatnonzero(status < 0), frame, weight, djump, s_old, self.p, s_new, d_new, fe, ke, status)

    def rp_points(self, frame, weight, djump, lam, aug, eps, pinned, s_old, d_old, mode_prev, s_new, d_new, fe,
                  ke, status, switched) -> None:
        """The RP form at every point (see the module docstring), with this law's parameters."""
        type(self).rp_kernel(frame, weight, djump, lam, aug, eps, pinned, s_old, d_old, mode_prev, self.p, s_new,
                             d_new, fe, ke, status, switched)
        rescue = type(self).rp_rescue_kernel
        if rescue is not None and status.min(initial=0) < 0:  # compiled when a run first needs it
            rescue(np.flatnonzero(status < 0), frame, weight, djump, lam, aug, eps, s_old, mode_prev, self.p, s_new,
                   d_new, fe, ke, status, switched)

    @abstractmethod
    def drive(self, jumps: np.ndarray) -> dict[str, np.ndarray]:
        """The EP form along total local jumps (n, 2) [m] from zero: step, jump_t, jump_n, the
        state's named slots and the records, one row per path point; RuntimeError if a point fails."""

    @abstractmethod
    def records(self, state: np.ndarray) -> dict[str, np.ndarray]:
        """The law's named per-point quantities (``record_names``) at states (n, n_state)."""

    @abstractmethod
    def flow(self, state: np.ndarray) -> np.ndarray:
        """Local flow directions dG/dT (n, 2) at the states' tractions (not normalised; zero where
        there is none): where each point opens or slides next."""

    @abstractmethod
    def yield_values(self, state: np.ndarray) -> np.ndarray:
        """The yield function F (n,) [Pa] at the states' tractions (> 0: outside)."""

    @abstractmethod
    def dissipation(self, state: np.ndarray) -> np.ndarray:
        """The energy (n,) [J/m^2] each point has dissipated up to its state, by the law's own
        account (the work that drives its softening)."""

    @abstractmethod
    def softening_modulus(self) -> float:
        """Upper estimate of the steepest softening slope [Pa/m] (a penalty or augmentation above it
        keeps the return unique)."""

    # -- shared ----------------------------------------------------------------------------------
    def elastic_energy(self, state: np.ndarray, weight: np.ndarray) -> float:
        """sum w (T_t^2 / kt + T_n^2 / kn) / 2 [J]: the penalty's stored energy (0 for RP)."""
        if self.rigid:
            return 0.0
        return float(0.5 * np.sum(weight * (state[:, S_TT] ** 2 / self.kt + state[:, S_TN] ** 2 / self.kn)))

    def initial_state(self, n: int) -> np.ndarray:
        """Virgin states (n, n_state)."""
        return np.zeros((n, self.n_state))

    def separated(self, state: np.ndarray, fraction: float = SEPARATED) -> np.ndarray:
        """(n,) True where a point has lost its tensile strength (down to ``fraction`` of its virgin
        one): the surface is a crack there, its two sides held only by contact and friction."""
        virgin = float(self.records(self.initial_state(1))[self.tensile_record][0])
        return self.records(state)[self.tensile_record] <= fraction * virgin
