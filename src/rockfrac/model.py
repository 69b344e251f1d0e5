"""The discrete system: dofs, element groups, conditions; assembles residual and tangent."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.sparse as sp

from rockfrac.compiled import kernel
from rockfrac.elements.base import ElementGroup
from rockfrac.fem.anderson import AndersonMixing
from rockfrac.fem.assembly import Pattern, scatter_matrix, scatter_vector


@kernel(fastmath={"reassoc"})
def serial_dot(x: np.ndarray, y: np.ndarray) -> float:
    """x . y on one thread (reassociated: the compiler vectorizes the sum, as BLAS does).

    Not NumPy's BLAS: from 1e4 entries OpenBLAS splits a dot product over its threads, and waking
    them cost up to 9 ms a call on a busy machine for microseconds of work (benchmarks/README.md,
    "Serial path for small systems"); the loop is also faster than one-threaded BLAS up to 1e6 entries.
    """
    s = 0.0
    for i in range(x.shape[0]):
        s += x[i] * y[i]
    return s


MIXING_DEPTH = 3  # the earlier updates of a step the nested multipliers' next update combines (Anderson)


@dataclass
class Assembled:
    """Residual r = f_int - f_ext (n,), tangent K (CSR), and the groups' verdict."""

    residual: np.ndarray
    f_int: np.ndarray
    matrix: sp.csr_matrix
    ok: bool
    n_switched: int
    message: str = ""
    local_residual: float = 0.0
    own: sp.csr_matrix | None = None  # an MPI rank's: its own elements' tangent on its local dofs (unreduced)


@dataclass
class Model:
    """Groups on a shared dof numbering: dim per node, then the groups' extra dofs.

    dirichlet: prescribed dof indices; the values come from the load path.
    """

    n_nodes: int
    groups: list[ElementGroup]
    dirichlet: np.ndarray
    dim: int = 2
    n_dofs: int = field(init=False, default=0)
    pattern: Pattern = field(init=False, repr=False)
    free: np.ndarray = field(init=False, repr=False)
    _const_data: np.ndarray | None = field(init=False, repr=False)  # None: no constant group
    _const_matrix: sp.csr_matrix | None = field(init=False, repr=False)
    _const_force: np.ndarray | None = field(init=False, default=None, repr=False)
    _bc_hit: np.ndarray = field(init=False, repr=False)
    _bc_diag: np.ndarray = field(init=False, repr=False)
    _mixing: AndersonMixing | None = field(init=False, default=None, repr=False)  # nested multipliers' updates

    def number_extras(self) -> int:
        """Number the groups' extra unknowns after the displacements; returns the number of dofs."""
        n = self.dim * self.n_nodes
        for g in self.groups:
            if g.extra_span():
                g.set_offset(n)
                n += g.extra_span()
        return n

    def __post_init__(self) -> None:
        self.n_dofs = self._number()
        self._build_structure()
        self.update_constant_force()
        self.set_dirichlet(self.dirichlet)

    def _number(self) -> int:
        """Number the dofs (an MPI rank's model: then renumber its groups locally); returns how many."""
        return self.number_extras()

    # -- the model's numbering against the global one (an MPI rank's is local) --------------------
    @property
    def n_u(self) -> int:
        """How many displacement dofs the model's vectors have (they come first)."""
        return self.dim * self.n_nodes

    @property
    def n_dofs_global(self) -> int:
        """How many dofs the whole model has (every rank's; what sizes a solver's choice)."""
        return self.n_dofs

    @property
    def n_u_global(self) -> int:
        """How many displacement dofs the whole model has (every rank's)."""
        return self.dim * self.n_nodes

    def local_dofs(self, dofs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(the model's numbers of those of the ``dofs`` of its mesh its vectors hold, where they are
        among ``dofs``): serially all of them, as they are; an MPI rank's local ones (of the dofs of its
        piece of the mesh, :mod:`rockfrac.mesh.piece`)."""
        dofs = np.asarray(dofs, dtype=np.int64)
        return dofs, np.ones(dofs.shape, dtype=bool)

    def global_dofs(self, dofs: np.ndarray) -> np.ndarray:
        """The whole model's numbers of dofs of the model's numbering (serially the same)."""
        return np.asarray(dofs, dtype=np.int64)

    def held_dofs(self, dofs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(the model's numbers of those of the whole model's ``dofs`` its vectors hold, where they are
        among ``dofs``): serially all of them; an MPI rank's local ones (:meth:`global_dofs` back)."""
        dofs = np.asarray(dofs, dtype=np.int64)
        return dofs, np.ones(dofs.shape, dtype=bool)

    def whole_dofs(self, dofs: np.ndarray) -> np.ndarray:
        """The whole model's numbers of dofs of the model's mesh (serially the same; an MPI rank's:
        of its piece of the mesh)."""
        return np.asarray(dofs, dtype=np.int64)

    def localized(self, f: np.ndarray) -> np.ndarray:
        """A vector over the first dofs of the model's mesh (the displacements, or all) as a vector of
        the model's (n_dofs,), zero on the others: an MPI rank keeps the entries of its local dofs (from
        a vector over its piece of the mesh)."""
        out = np.zeros(self.n_dofs)
        out[: f.shape[0]] = f
        return out

    def summed(self, f: np.ndarray) -> np.ndarray:
        """The sum over the ranks of vectors over the first dofs of their meshes, each rank's from its
        own cells and sides of its piece, as a vector of the model's (serial: :meth:`localized`)."""
        return self.localized(f)

    def _pattern_rows(self) -> tuple[int, np.ndarray | None]:
        """The matrix's size and each dof's row in it (None: the dof numbering itself); an MPI rank's
        model numbers only its local dofs (rockfrac.parallel.model)."""
        return self.n_dofs, None

    def _build_structure(self) -> None:
        """The sparsity pattern of the groups' dofs, the constant groups' part of the matrix."""
        n, row = self._pattern_rows()
        self._structure = tuple(g.structure_version() for g in self.groups)
        self.pattern = Pattern.build(n, [g.dofs if row is None else row[g.dofs] for g in self.groups])
        data = np.zeros(self.pattern.nnz)
        for g, slots in zip(self.groups, self.pattern.slots):
            if g.constant:
                g.assemble_constant(data, slots)
            g.reuse_buffers = True  # its element arrays are scattered at once: they may be refilled
        # a constant group's slot map is used once, here: dropped (256 MB at 1e6 quads); the others'
        # are copied out of the pattern's single slot array, which is then freed
        self.pattern.slots = [np.zeros((0,) + sl.shape[1:], dtype=sl.dtype) if g.constant else sl.copy()
                              for g, sl in zip(self.groups, self.pattern.slots)]
        constant = any(g.constant for g in self.groups)  # else no matrix of zeros is kept (nnz floats)
        self._const_data = data if constant else None
        self._const_matrix = self.pattern.matrix(data) if constant else None

    def refresh_structure(self) -> bool:
        """Make the pattern again if a group's dofs changed (cells cut by a nodal crack); True if so."""
        if tuple(g.structure_version() for g in self.groups) == self._structure:
            return False
        self._build_structure()
        self.set_dirichlet(self.dirichlet)
        return True

    def update_constant_force(self) -> None:
        """Collect the constant groups' constant element vectors (their in-situ stress) into f_int."""
        forces = [(g, f) for g in self.groups if g.constant and (f := g.constant_force()) is not None]
        self._const_force = None
        if forces:
            self._const_force = np.zeros(self.n_dofs)
            for g, f in forces:
                scatter_vector(self._const_force, g.dofs, f)

    def set_dirichlet(self, dofs: np.ndarray) -> None:
        """Prescribe ``dofs`` (and the extra dofs they make redundant) from now on; the rest is free."""
        redundant = [g.redundant_extras(dofs) for g in self.groups]
        self.dirichlet = np.unique(np.concatenate([np.asarray(dofs, dtype=np.int64), *redundant])).astype(np.int64)
        free = np.ones(self.n_dofs, dtype=np.bool_)
        free[self.dirichlet] = False
        self.free = np.flatnonzero(free)
        self._bc_hit, self._bc_diag = self._dirichlet_positions()

    def _dirichlet_positions(self) -> tuple[np.ndarray, np.ndarray]:
        """Where the prescribed rows and columns, and their diagonals, are in the matrix's data."""
        return self.pattern.positions(self.dirichlet)

    def _constant_forces(self, u: np.ndarray) -> np.ndarray:
        """The constant groups' internal forces K_const u (n_dofs,)."""
        assert self._const_matrix is not None
        return self._const_matrix @ u

    def initial_unknowns(self) -> np.ndarray:
        """The global vector at t = 0: zero displacements, the groups' initial extra unknowns."""
        u0 = np.zeros(self.n_dofs)
        for g in self.groups:
            g.initial_unknowns(u0)
        return u0

    def begin_step(self) -> None:
        for g in self.groups:
            g.begin_step()
        if self._mixing is not None:
            self._mixing.reset()

    def set_step(self, mode: str, size: float) -> None:
        """Tell the groups the control and size of the step about to be solved."""
        for g in self.groups:
            g.set_step(mode, size)

    def implex_error(self) -> float | None:
        """The largest IMPL-EX error of the groups at the converged iterate (None: no IMPL-EX group)."""
        errors = [e for e in (g.implex_error() for g in self.groups) if e is not None]
        return max(errors) if errors else None

    def switch_to_implex(self) -> bool:
        """Switch every group that can to IMPL-EX integration; True if one did."""
        return any([g.switch_to_implex() for g in self.groups])

    def commit(self) -> None:
        for g in self.groups:
            g.commit()

    def _held(self) -> list[tuple[ElementGroup, tuple[np.ndarray, np.ndarray, np.ndarray]]]:
        return [(g, h) for g in self.groups if (h := g.held_multipliers()) is not None]

    def multiplier_gap(self) -> float:
        """The Euclidean norm [N] of the residual w (T - lambda) of the constraint rows held outside the
        unknowns (the nested RP surfaces', on every rank), at the last assembly; 0 without such rows."""
        total = sum(float(np.einsum("p,pi,pi->", w * w, t - lam, t - lam)) for _, (lam, t, w) in self._held())
        return math.sqrt(self.reduce_sum(total))

    def holds_multipliers(self) -> bool:
        """True if a group holds multipliers outside the unknowns (a nested RP surface)."""
        return bool(self._held())

    def constrain_all(self, on: bool) -> None:
        """Hold, or stop holding, every point of the nested RP surfaces constrained
        (:meth:`ElementGroup.constrain_all`)."""
        for g in self.groups:
            g.constrain_all(on)

    def augment(self) -> None:
        """Move the nested RP surfaces' multipliers towards their last tractions: lambda := T, Anderson
        mixed with the step's earlier updates (:mod:`rockfrac.fem.anderson`)."""
        held = self._held()
        if not held:
            return
        lam = np.concatenate([h[0].ravel() for _, h in held])
        t = np.concatenate([h[1].ravel() for _, h in held])
        w2 = np.concatenate([np.repeat(h[2] * h[2], h[0].shape[1]) for _, h in held])
        if self._mixing is None:
            self._mixing = AndersonMixing(MIXING_DEPTH, self.reduce_sum)
        new = self._mixing.next(lam, t, w2)
        at = 0
        for g, (lam_g, _, _) in held:
            g.hold_multipliers(new[at:at + lam_g.size].reshape(lam_g.shape))
            at += lam_g.size

    def enrichment_version(self) -> tuple[int, ...] | None:
        """The groups' enrichment counters (None: no group has enriched unknowns); a change means the
        external forces' share on them must be made again (:meth:`enriched_surface_forces`)."""
        versions = tuple(v for v in (g.enrichment_version() for g in self.groups) if v is not None)
        return versions or None

    def enriched_surface_forces(self, edges: np.ndarray, tractions: np.ndarray) -> np.ndarray:
        """The enriched unknowns' share (n_dofs,) of tractions [Pa] at the nodes (m, s, dim) of boundary
        sides (m, s) (edges in 2D, faces in 3D)."""
        return self._groups_sum([g.enriched_surface_forces(edges, tractions, self.n_dofs) for g in self.groups])

    def enriched_body_forces(self, body: dict[str, np.ndarray]) -> np.ndarray:
        """The enriched unknowns' share (n_dofs,) of body forces [N/m^3] per region (density x g)."""
        return self._groups_sum([g.enriched_body_forces(body, self.n_dofs) for g in self.groups])

    def _groups_sum(self, parts: list[np.ndarray | None]) -> np.ndarray:
        """The sum (n_dofs,) of the groups' vectors (None: a group without any)."""
        out = np.zeros(self.n_dofs)
        for f in parts:
            if f is not None:
                out += f
        return out

    def event(self) -> tuple[float, float] | None:
        """(committed, trial) values of the groups' event indicator (e.g. min det A / det A^e), or None.

        An event happens in a step where the indicator crosses zero; the stepping then shortens the
        step so that it ends at the event (within its tolerance).
        """
        pairs = [(c, t) for c, t in ((g.committed_event(), g.event()) for g in self.groups)
                 if c is not None and t is not None]
        if not pairs:
            return None
        return min(p[0] for p in pairs), min(p[1] for p in pairs)

    def growth_waiting(self) -> bool:
        """True if a group, on any rank, asks for a step at the same load after the last commit (its
        cuts: :meth:`rockfrac.elements.base.ElementGroup.growth_waiting`)."""
        return self.reduce_any(any([g.growth_waiting() for g in self.groups]))

    def assemble(self, u: np.ndarray, u_n: np.ndarray, f_ext: np.ndarray) -> Assembled:
        """Residual and consistent tangent at u (trial state from the committed one at u_n)."""
        self.refresh_structure()
        if self._const_data is not None and self._const_matrix is not None:
            data = self._const_data.copy()
            f_int = self._constant_forces(u)
        else:
            data, f_int = np.zeros(self.pattern.nnz), np.zeros(self.n_dofs)
        if self._const_force is not None:
            f_int += self._const_force
        ok, switched, msgs, local = True, 0, [], 0.0
        for g, slots in zip(self.groups, self.pattern.slots):
            if g.constant:
                continue
            ev = g.evaluate(u, u_n)
            ok &= ev.ok
            switched += ev.n_switched
            local = max(local, ev.local_residual)
            if ev.message:
                msgs.append(ev.message)
            scatter_vector(f_int, g.dofs, ev.fe)
            scatter_matrix(data, slots, ev.ke)
        return Assembled(f_int - f_ext, f_int, self.pattern.matrix(data), ok, switched, "; ".join(msgs), local)

    # -- the reductions of the solvers (a distributed model sums over its ranks) ------------------
    distributed = False  # True for a model of one rank's elements (rockfrac.parallel)

    def _part(self, part: str) -> np.ndarray | slice | None:
        return {"free": self.free, "dirichlet": self.dirichlet, "all": None, "u": slice(0, self.n_u)}[part]

    def dot(self, x: np.ndarray, y: np.ndarray, part: str = "free") -> float:
        """x . y over the dofs of ``part``: "free", "dirichlet", "all" or "u" (the displacements)."""
        idx = self._part(part)
        return serial_dot(x, y) if idx is None else serial_dot(x[idx], y[idx])

    def norm(self, x: np.ndarray, part: str = "free") -> float:
        """The Euclidean norm of x over the dofs of ``part``."""
        return math.sqrt(self.dot(x, x, part))

    def gradient_dot(self, grad: np.ndarray, x: np.ndarray) -> float:
        """grad . x for the gradient of a path measure (on a distributed model each rank holds the
        part of the gradient from its own elements)."""
        return serial_dot(grad, x)

    def gradient_norm(self, grad: np.ndarray) -> float:
        """|grad| of a path measure's gradient (distributed: the square root of the ranks' sum of
        their parts' squares, a scale for the test of a rigid constraint)."""
        return math.sqrt(serial_dot(grad, grad))

    def reduce_all_finite(self, x: np.ndarray) -> bool:
        """True if every entry of x is finite (on every rank)."""
        return bool(np.all(np.isfinite(x)))

    def reduce_sum(self, value: Any) -> Any:
        """The sum of a value (a number or an array) over the ranks (serial: the value)."""
        return value

    def reduce_any(self, flag: bool) -> bool:
        """True if the flag is true on any rank (serial: the flag)."""
        return flag

    def reduce_min(self, value: float) -> float:
        """The smallest of a value over the ranks (serial: the value)."""
        return value

    def reduce_max(self, value: Any) -> Any:
        """The largest of a value (a number or an array, entry by entry) over the ranks (serial: the value)."""
        return value

    def gather(self, x: np.ndarray) -> np.ndarray:
        """The whole vector in the global numbering (a distributed model's ranks hold their local dofs only)."""
        return x

    def gather_records(self, records: dict[str, np.ndarray] | None, order: np.ndarray | None
                       ) -> dict[str, np.ndarray] | None:
        """The point records of a group over every rank, in the group's order (serial: as they are)."""
        return records

    def share(self, value: Any) -> Any:
        """Rank 0's value on every rank (serial: the value)."""
        return value

    def allgather(self, value: Any) -> list[Any]:
        """Every rank's value, in rank order, on every rank (serial: [value])."""
        return [value]

    def values_at(self, x: np.ndarray, dofs: np.ndarray) -> np.ndarray:
        """x at the given dofs of the model's mesh (an MPI rank's piece), each from the rank that owns
        it (a collective call on MPI ranks, which may ask for different dofs; serial: x[dofs])."""
        return x[dofs]

    def gather_lead(self, value: Any) -> list[Any] | None:
        """Every rank's value, in rank order, on rank 0, None on the others (serial: [value])."""
        return [value]

    def exchange(self, parts: list[Any]) -> list[Any]:
        """parts[r] sent to rank r; what every rank sent to this one, in rank order (serial: parts)."""
        return parts

    def local_signature(self) -> str:
        """The SHA-256 of the global dofs of the model's vectors' entries ("" serially: all of them, in order)."""
        return ""

    def checked_vector(self, values: np.ndarray) -> np.ndarray:
        """A vector read back (a checkpoint's) as one of the model's: ValueError for another length."""
        if values.shape != (self.n_dofs,):
            raise ValueError(f"{values.shape[0]} entries, this model has {self.n_dofs} dofs")
        return values.astype(float)

    def owned(self, x: np.ndarray) -> np.ndarray:
        """x on the dofs this rank owns, zero elsewhere: a vector each dof of which is held by one
        rank only, so that dot products sum over the ranks (serial: x)."""
        return x

    def agree(self, failure: str | None) -> str | None:
        """The first rank's failure, on every rank (serial: the failure): a check that may fail on one
        rank only ends them all."""
        return failure

    def apply_dirichlet(self, a: sp.csr_matrix) -> sp.csr_matrix:
        """Zero prescribed rows and columns, unit diagonal (the increment there is set by the rhs)."""
        a.data[self._bc_hit] = 0.0
        a.data[self._bc_diag] = 1.0
        return a
