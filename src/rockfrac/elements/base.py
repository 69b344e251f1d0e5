"""The element-group contract: what every group (bulk, cohesive, embedded) gives the problem.

A group owns a set of cells (or interface points) of one kind, their dofs, their committed and
trial state, and their kernels. The problem and the output talk to groups only through the
methods of :class:`ElementGroup`; a capability a group does not have is a method that says so
(``event`` returns None, ``path_measure`` returns None, ``point_records`` returns None...), never
an attribute probed from outside.

State: ``begin_step`` copies the committed state to the trial one, ``evaluate`` works on the trial
state only, ``commit`` copies it back after a converged step (Ferrite's "commit once").
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from rockfrac.fem.dofs import Numbering
from rockfrac.fem.loads import StressField

#: A path-following measure g(u) and its gradient dg/du (dense, n_dofs).
Measure = Callable[[np.ndarray], tuple[float, np.ndarray]]


@dataclass
class Evaluation:
    """Element vectors fe (n_el, nd), blocks ke (n_el, nd, nd); ok False if a local solve failed."""

    fe: np.ndarray
    ke: np.ndarray
    ok: bool = True
    n_switched: int = 0
    message: str = ""
    local_residual: float = 0.0  # relative residual of element-level equations (condensed unknowns)


class ElementGroup(ABC):
    """A group of elements of one kind on the model's dof numbering.

    dofs: (n_el, nd) dof indices of each element's vector and block (global, or an MPI
    rank's local one after :meth:`renumber`).
    n_extra: unknowns the group owns beyond the displacements (RP multipliers), numbered by
    :meth:`set_offset`. constant: its tangent never changes and its residual is linear (assembled
    once through :meth:`assemble_constant`). name: how output names it (a region or a set).
    """

    name: str = ""
    kind: str = "bulk"  # "bulk", "cohesive" or "embedded" (how output groups its records)
    n_extra: int = 0
    constant: bool = False
    reuse_buffers: bool = False  # the problem scatters each Evaluation at once: buffers may be reused
    checkpoint_attrs: tuple[str, ...] = ()
    dofs: np.ndarray

    # -- the discrete equations --------------------------------------------------------------
    def set_offset(self, offset: int) -> None:
        """Number the group's extra unknowns from ``offset`` (groups without extras: nothing)."""

    def extra_span(self) -> int:
        """How many extra dofs the group's numbering takes: its own (n_extra), or on an MPI rank, the
        whole set's (every rank numbers every set's extras alike)."""
        return self.n_extra

    @abstractmethod
    def evaluate(self, u: np.ndarray, u_n: np.ndarray) -> Evaluation:
        """Element vectors and consistent tangent blocks at u, the trial state from the committed one
        (at u_n)."""

    def assemble_constant(self, data: np.ndarray, slots: np.ndarray) -> None:
        """data[slots] += the constant element blocks (constant groups only)."""
        raise NotImplementedError(f"{type(self).__name__} is not a constant group")

    def constant_force(self) -> np.ndarray | None:
        """Constant part of the element vectors (n_el, nd) [N], added to f_int at every evaluation of a
        constant group (the in-situ stress of an elastic group); None if there is none."""
        return None

    def redundant_extras(self, dirichlet: np.ndarray) -> np.ndarray:
        """Extra dofs whose equation the Dirichlet set already imposes (prescribed to zero instead)."""
        return np.zeros(0, dtype=np.int64)

    def reach(self) -> np.ndarray:
        """Every dof the group may ever touch (in the numbering it has now): its ``dofs``, and for a group
        whose dofs grow (cells cut by a nodal crack) those they may grow to. An MPI rank keeps vectors
        on these dofs of its groups, fixed for the run."""
        return self.dofs.ravel()

    def renumber(self, numbering: Numbering) -> None:
        """Put every dof the group holds into an MPI rank's local numbering (from the global one)."""
        self.dofs = numbering.local(self.dofs)

    def structure_version(self) -> int:
        """A counter that changes whenever the group's ``dofs`` change (cells cut by a nodal crack); the
        model then makes its sparsity pattern again. Most groups' dofs never change: 0."""
        return 0

    def companions(self) -> list[ElementGroup]:
        """Groups this one adds to the model beside itself (a nodal crack's cut cells and unknowns)."""
        return []

    def enrichment_version(self) -> int | None:
        """A counter that grows whenever the group's enriched unknowns change (None: it has none)."""
        return None

    def enriched_surface_forces(self, edges: np.ndarray, tractions: np.ndarray, n_dofs: int) -> np.ndarray | None:
        """The enriched unknowns' share (n_dofs,) of tractions [Pa] at the nodes (m, s, dim) of boundary
        sides (m, s) (a crack crossing a loaded boundary splits its load between the two sides); None:
        no share."""
        return None

    def enriched_body_forces(self, body: dict[str, np.ndarray], n_dofs: int) -> np.ndarray | None:
        """The enriched unknowns' share (n_dofs,) of body forces [N/m^3] per region; None: no share."""
        return None

    # -- state -------------------------------------------------------------------------------
    def set_initial_stress(self, stress: StressField) -> None:
        """Start from the in-situ stress field ``stress`` (points -> Voigt stresses [Pa]) instead of a
        stress-free state: the committed state at t = 0 carries it, nothing moves or yields."""

    def initial_unknowns(self, u0: np.ndarray) -> None:
        """Write the group's extra unknowns at t = 0 (RP multipliers) into the global vector u0."""

    def initial_violation(self) -> str:
        """Where the state at t = 0 lies outside the yield surface ('' if nowhere)."""
        return ""

    def begin_step(self) -> None:
        """Start a step: the trial state is the committed one."""

    def switch_to_implex(self) -> bool:
        """Integrate with IMPL-EX from the next step on (the [solver] fallback); True if the group
        switched (it could, and was not already)."""
        return False

    def implex_error(self) -> float | None:
        """The IMPL-EX error of the converged step, relative (None: the group does not use IMPL-EX)."""
        return None

    def set_step(self, mode: str, size: float) -> None:
        """The step about to be solved: its control ("load" or "path") and its increment of that
        control's parameter (load factor or path measure); groups that integrate in time use it."""

    def commit(self) -> None:
        """Make the trial state the committed one (after a converged step)."""

    # -- multipliers held outside the unknowns (nested augmented Lagrangian) ------------------
    def held_multipliers(self) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """(lambda, T, w): the multipliers the group holds outside the unknowns (n_pts, dim), global frame
        [Pa], the tractions of its last evaluation that they must equal, and the points' weights
        (n_pts,) [m, or m^2 in 3D] (a nested RP surface, :mod:`rockfrac.elements.cse_nested`); None for a
        group without."""
        return None

    def constrain_all(self, on: bool) -> None:
        """While on, a group with held multipliers holds every point constrained (its linear response
        before anything yields); nothing for the others."""

    def hold_multipliers(self, lam: np.ndarray) -> None:
        """Set the held multipliers (n_pts, dim) [Pa] (groups with :meth:`held_multipliers` only)."""
        raise NotImplementedError(f"{type(self).__name__} holds no multipliers")

    def checkpoint_state(self) -> dict[str, np.ndarray]:
        """The committed state as named arrays (copies)."""
        return {a: np.array(getattr(self, a)) for a in self.checkpoint_attrs}

    def restore_checkpoint(self, saved: dict[str, np.ndarray]) -> None:
        """Put a :meth:`checkpoint_state` back (same model); ValueError if it does not fit."""
        restore_arrays(self, saved, self.checkpoint_attrs, type(self).__name__)

    # -- events and path following -------------------------------------------------------------
    def event(self) -> float | None:
        """Event indicator of the trial (converged, uncommitted) state, or None if the group has no
        events; an event happens in a step where it crosses zero from its committed value."""
        return None

    def committed_event(self) -> float | None:
        """The event indicator of the committed state (None: no events)."""
        return None

    def growth_waiting(self) -> bool:
        """True if the last commit changed the group so that the next step should re-solve at the same
        load first (an embedded crack's cuts: the stress they release, and the cells at its new tips
        that wait for it)."""
        return False

    def event_log(self) -> list[str]:
        """One line per event so far (e.g. "bifurcation: ..."), in order; the log prints the new ones."""
        return []

    def localized_count(self) -> int:
        """How many cells carry an embedded discontinuity (0 for other groups)."""
        return 0

    def path_measure(self, n_dofs: int) -> Measure | None:
        """The group's crack-opening measure for path following over the next step (None: none)."""
        return None

    def path_active(self) -> bool:
        """True if the committed state has a crack that opens or slides (path control may take over)."""
        return False

    def activation_pending(self) -> bool:
        """True while the group is a surface none of whose points has yielded yet (its first
        activation, the peak of a crack, is then located by the stepping)."""
        return False

    def activation(self, u: np.ndarray, du: np.ndarray) -> float | None:
        """The fraction s in (0, 1] of the increment du from the committed u at which a point of a
        pending surface first reaches its yield surface along the elastic response (None: none)."""
        return None

    def yielded(self) -> bool:
        """True if a point of the step's trial state has yielded (a pending surface activated in it)."""
        return False

    def path_weight(self) -> int:
        """How many points the path measure averages over (to combine several groups)."""
        return 0

    def path_count(self) -> int:
        """How many points this group's measure averages over now (0 allowed; on several MPI ranks,
        this rank's): the ranks' sum, at least 1, is :meth:`path_weight` of the whole group."""
        return self.path_weight()

    def measure_mass(self) -> float:
        """The total weight of the points in the path measure's own average (the integration weights
        of cohesive points): what combines the parts of one group held by several MPI ranks."""
        return float(self.path_weight())

    # -- output ------------------------------------------------------------------------------
    def point_records(self, u: np.ndarray) -> dict[str, np.ndarray] | None:
        """Committed per-point quantities of the discontinuities (points.csv), or None."""
        return None

    def record_order(self) -> np.ndarray | None:
        """Each record's place among those of the whole group (the group of one MPI rank holds some
        of its points); None: the group has no point records."""
        return None

    def elastic_energy(self, u: np.ndarray) -> float:
        """Elastic energy stored in the group at the committed state [J] (per unit thickness in 2D)."""
        return 0.0

    def dissipated_energy(self) -> float:
        """Energy dissipated by the group up to the committed state [J] (per unit thickness in 2D)."""
        return 0.0

    def surface_energy(self) -> float:
        """The work of the traction laws on the group's crack surfaces up to the committed state [J]
        (its share of the dissipation that a surface law defines; 0 for a bulk group)."""
        return 0.0

    def recut_energy(self) -> float:
        """The stored energy [J] (per unit thickness in 2D) that the group's cells gained, at fixed
        displacement, when they were cut and integrated anew (nodal embedded cracks; 0 for others)."""
        return 0.0

    def viscous_energy(self) -> float | None:
        """The part of :meth:`dissipated_energy` that a viscous regularisation added [J] (per unit
        thickness in 2D); None for a group without one."""
        return None

    def bending_energy(self) -> float | None:
        """The part of :meth:`dissipated_energy` that facet points' plastic bending took [J] (per unit
        thickness in 2D); None for a group without bending."""
        return None


def restore_arrays(owner: object, saved: dict[str, np.ndarray], names: tuple[str, ...], what: str) -> None:
    """Copy the saved arrays ``names`` into ``owner``'s arrays of the same names, in place; ValueError
    if one is missing or differs in shape or kind (a checkpoint of another model)."""
    for name in names:
        if name not in saved:
            raise ValueError(f"the checkpoint has no {what}.{name}: it was written for a different model")
        current = getattr(owner, name)
        value = saved[name]
        if isinstance(current, np.ndarray):
            if current.shape != value.shape or current.dtype.kind != value.dtype.kind:
                raise ValueError(f"the checkpoint was written for a different model ({what}.{name}: "
                                 f"{value.shape} {value.dtype} here {current.shape} {current.dtype})")
            current[...] = value
        else:
            setattr(owner, name, type(current)(value.item()))
