"""One MPI rank's model: its elements' groups, assembled into PETSc's distributed matrix and vectors.

Every rank builds its groups on its piece of the split mesh (:mod:`rockfrac.case.shares`), holding
only its own cells and interface cells, whose state stays on the rank, and knows of the partition
(:mod:`rockfrac.mesh.partition`) only its piece's share. The extra dofs are numbered alike on every
rank (the global numbering); then the groups, built on the piece's node numbers, are renumbered into
the rank's local numbering (:class:`rockfrac.parallel.layout.Layout`,
:class:`rockfrac.fem.dofs.PieceNumbering`), in which all its vectors are: none has the whole
model's length. ``assemble`` runs the groups as the serial model does, then:

- the internal forces are summed over the ranks in a PETSc vector (each rank adds its elements'
  contributions, owned or not) and brought back to the local entries;
- the tangent goes into an ``MPIAIJ`` matrix preallocated once from the exact pattern of the owned
  rows (each rank sends the pattern of the rows it touches but does not own to their owners), with
  the local-to-global map of the local dofs; a new nonzero after that is an error, not a
  reallocation. The rank's sparsity pattern is built on its local dofs in PETSc order, so the
  groups scatter their blocks straight into the local CSR that PETSc takes (one pattern, no map
  from rockfrac's numbering to PETSc's).

Norms and dot products sum over the owned dofs of every rank (each dof counted once), the
verdicts of the groups (a failed return, an event, the activation of a surface) are reduced over
the ranks, so that Newton and the stepping take the same decisions on every rank.
"""

from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.sparse as sp

from rockfrac.fem.dofs import PieceNumbering, piece_to_global
from rockfrac.mesh.partition import RankPartition
from rockfrac.model import Assembled, Model, serial_dot
from rockfrac.parallel.layout import Layout, petsc


class DistributedMatrix:
    """The tangent of a distributed model: a PETSc MPIAIJ matrix in the partition's numbering."""

    def __init__(self, mat, layout: Layout):
        self.mat, self.layout = mat, layout

    def __matmul__(self, x: np.ndarray) -> np.ndarray:
        """A x on the owned entries of a local vector (x read on its owned entries)."""
        y, xv = self.layout.new_vec(), self.layout.to_vec(x)
        self.mat.mult(xv, y)
        out = np.zeros(self.layout.local.shape[0])
        out[self.layout.owned_local] = y.getArray()
        y.destroy()
        xv.destroy()
        return out


@dataclass
class DistributedModel(Model):
    """The groups of one rank's elements on the partition's dofs (see the module note)."""

    comm: Any = None  # the mpi4py communicator of the run
    partition: RankPartition | None = None  # this rank's share of the partition (its piece's)
    rank: int = 0
    nodes: np.ndarray | None = None  # the coordinates of the rank's piece of the mesh [m]
    layout: Layout = field(init=False, repr=False)
    distributed = True

    def __post_init__(self) -> None:
        assert self.partition is not None and self.comm is not None and self.nodes is not None
        super().__post_init__()
        self._matrix = self._preallocated()

    def _number(self) -> int:
        """Number every rank's extra dofs alike (global numbering), then put the groups, numbered on
        the rank's piece of the mesh, into its local numbering: its vectors have its local dofs only."""
        part = self.partition
        assert part is not None and self.nodes is not None
        n = self.number_extras()  # the multipliers numbered over every rank's points
        if n != part.n_dofs:
            raise ValueError(f"the partition has {part.n_dofs} dofs, the model {n}: its extra dofs "
                             "(rigid-plastic multipliers, nodal cracks' enrichments) are not partitioned")
        reach = [piece_to_global(g.reach(), self.dim, part.node_ids) for g in self.groups]
        self.layout = Layout(self.comm, part, np.concatenate(reach + [np.zeros(0, dtype=np.int64)]), self.nodes)
        self.piece = PieceNumbering(self.layout.numbering, self.dim, part.node_ids, part.n_nodes)
        for g in self.groups:
            g.renumber(self.piece)
        local = self.layout.local
        u = local[:self.layout.n_local_u]  # the local displacement dofs, whole mesh's numbering
        self._piece_u = self.piece.from_global(u)  # their dofs on the piece of the mesh
        self._row = self.layout.row_of.astype(np.int32 if local.shape[0] < 2**31 else np.int64)
        return int(local.shape[0])

    @property
    def n_u(self) -> int:
        return self.layout.n_local_u

    @property
    def n_dofs_global(self) -> int:
        return self.layout.n

    def local_dofs(self, dofs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return self.piece.local_part(dofs)

    def global_dofs(self, dofs: np.ndarray) -> np.ndarray:
        return self.layout.numbering.global_(dofs)

    def held_dofs(self, dofs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return self.layout.numbering.local_part(dofs)

    def whole_dofs(self, dofs: np.ndarray) -> np.ndarray:
        return self.piece.to_global(dofs)

    def localized(self, f: np.ndarray) -> np.ndarray:
        """f over the displacement dofs of the rank's piece of the mesh, on the local dofs."""
        at = self._piece_u
        inside = at < f.shape[0]
        out = np.zeros(self.n_dofs)
        out[:at.shape[0]][inside] = f[at[inside]]
        return out

    def summed(self, f: np.ndarray) -> np.ndarray:
        return self.layout.sum_local(self.localized(f))

    def _pattern_rows(self) -> tuple[int, np.ndarray | None]:
        """The rank's matrix is numbered on its local dofs in PETSc order: its pattern is the local
        CSR that PETSc takes (no pattern in rockfrac's numbering, no map between the two)."""
        return self.layout.local.shape[0], self._row

    def _dirichlet_positions(self) -> tuple[np.ndarray, np.ndarray]:
        empty = np.zeros(0, dtype=np.int64)
        return empty, empty  # PETSc zeroes the prescribed rows (apply_dirichlet)

    def _constant_forces(self, u: np.ndarray) -> np.ndarray:
        assert self._const_matrix is not None
        rows = self.layout.rows
        out = np.zeros(self.n_dofs)
        out[rows] = self._const_matrix @ u[rows]
        return out

    def refresh_structure(self) -> bool:
        """As the serial model, then the preallocated matrix made again: a cut cell of a nodal crack
        brings its enrichments (every rank at once: the registry's cuts are the same on every rank).
        The local dofs stay: they include every enrichment a cut may bring (the groups' reach)."""
        if tuple(g.structure_version() for g in self.groups) == self._structure:
            return False
        super().refresh_structure()
        self._matrix.destroy()
        self._matrix = self._preallocated()
        return True

    def _preallocated(self):
        """The MPIAIJ matrix with the exact pattern of the owned rows, every rank's elements included.

        The local dofs are in PETSc order, so the owned rows are one slice of the local rows, their
        columns ascending; only the rows of ghost dofs (the partition's surface) go to their owners,
        which add the columns they bring to those rows."""
        PETSc, lay = petsc(), self.layout
        indptr, columns = self._csr()
        a, b = np.searchsorted(lay.rows_petsc, [lay.lo, lay.hi])
        ghost = np.r_[0:a, b:lay.rows_petsc.shape[0]]
        lengths = np.diff(indptr)[ghost]
        entries = np.repeat(indptr[ghost] - (np.cumsum(lengths) - lengths), lengths) + np.arange(lengths.sum())
        rows = np.repeat(lay.rows_petsc[ghost], lengths).astype(np.int64)
        cols = lay.rows_petsc[columns[entries]].astype(np.int64)
        owner = lay.owner(rows)
        got = lay.comm.alltoall([(rows[owner == r], cols[owner == r]) for r in range(lay.size)])
        row_ptr = indptr[a:b + 1] - indptr[a]
        owned_cols = lay.rows_petsc[columns[indptr[a]:indptr[b]]]  # ascending in each row
        extra_rows = np.concatenate([r for r, _ in got]) - lay.lo
        if extra_rows.size:  # the union of this rank's columns and the others' in the shared rows
            shape = (lay.hi - lay.lo, lay.n)
            mine = sp.csr_matrix((np.ones(owned_cols.shape[0], np.float32), owned_cols, row_ptr), shape=shape)
            theirs = sp.csr_matrix((np.ones(extra_rows.shape[0], np.float32),
                                    (extra_rows, np.concatenate([c for _, c in got]))), shape=shape)
            union = mine + theirs
            union.sum_duplicates()  # and its columns sorted
            row_ptr, owned_cols = union.indptr, union.indices
        mat = PETSc.Mat().createAIJ(((lay.hi - lay.lo, lay.n), (lay.hi - lay.lo, lay.n)), bsize=self.dim,
                                    comm=lay.comm)
        mat.setPreallocationCSR((row_ptr.astype(PETSc.IntType), owned_cols.astype(PETSc.IntType)))
        mat.setLGMap(lay.lgmap, lay.lgmap)
        mat.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, True)
        mat.setOption(PETSc.Mat.Option.KEEP_NONZERO_PATTERN, True)
        return mat

    def _build_structure(self) -> None:
        """The serial model's pattern (here on the local dofs), and its arrays in PETSc's index type,
        made once for every assembly (the columns are not copied when the types agree)."""
        super()._build_structure()
        PETSc = petsc()
        self._petsc_csr = (self.pattern.indptr.astype(PETSc.IntType, copy=False),
                           self.pattern.indices.astype(PETSc.IntType, copy=False))

    def _csr(self) -> tuple[np.ndarray, np.ndarray]:
        """The rank's pattern (local rows and columns in PETSc order) with PETSc's index type."""
        return self._petsc_csr

    def set_dirichlet(self, dofs: np.ndarray) -> None:
        super().set_dirichlet(dofs)
        owned = self.layout.owned_mask
        self._dirichlet_owned = self.dirichlet[owned[self.dirichlet]]
        self._free_owned = self.free[owned[self.free]]
        self._dirichlet_rows = self.layout.local_petsc[self._dirichlet_owned].astype(petsc().IntType)

    def assemble(self, u: np.ndarray, u_n: np.ndarray, f_ext: np.ndarray) -> Assembled:
        """The residual (on the local dofs) and the distributed tangent; the verdicts over all ranks."""
        local = super().assemble(u, u_n, np.zeros_like(f_ext))  # the rank's own f_int, unreduced
        verdicts = self.comm.allgather((local.ok, local.n_switched, local.local_residual, local.message))
        f_int = self.layout.sum_local(local.f_int)
        mat = self._matrix
        mat.zeroEntries()
        PETSc = petsc()
        mat.setValuesLocalCSR(*self._csr(), local.matrix.data, addv=PETSc.InsertMode.ADD_VALUES)
        mat.assemble()
        return Assembled(f_int - f_ext, f_int, DistributedMatrix(mat, self.layout),
                         all(v[0] for v in verdicts), sum(v[1] for v in verdicts),
                         "; ".join(v[3] for v in verdicts if v[3]), max(v[2] for v in verdicts), own=local.matrix)

    def apply_dirichlet(self, a):
        """Zero the prescribed rows and columns of the distributed tangent, unit diagonal."""
        a.mat.zeroRowsColumns(self._dirichlet_rows, diag=1.0)
        return a

    def enriched_surface_forces(self, edges: np.ndarray, tractions: np.ndarray) -> np.ndarray:
        """Each rank's cut cells' share, summed over the ranks."""
        return self.layout.sum_local(super().enriched_surface_forces(edges, tractions))

    def enriched_body_forces(self, body: dict[str, np.ndarray]) -> np.ndarray:
        """Each rank's cut cells' share, summed over the ranks."""
        return self.layout.sum_local(super().enriched_body_forces(body))

    # -- reductions over the ranks ---------------------------------------------------------------
    def _owned(self, part: str) -> np.ndarray:
        if part == "u":
            owned = self.layout.owned_local
            return owned[owned < self.n_u]
        return {"free": self._free_owned, "dirichlet": self._dirichlet_owned, "all": self.layout.owned_local}[part]

    def dot(self, x: np.ndarray, y: np.ndarray, part: str = "free") -> float:
        idx = self._owned(part)
        return self.comm.allreduce(serial_dot(x[idx], y[idx]))

    def gradient_dot(self, grad: np.ndarray, x: np.ndarray) -> float:
        return self.comm.allreduce(serial_dot(grad, x))

    def gradient_norm(self, grad: np.ndarray) -> float:
        return math.sqrt(self.comm.allreduce(serial_dot(grad, grad)))

    def reduce_all_finite(self, x: np.ndarray) -> bool:
        return self.comm.allreduce(bool(np.all(np.isfinite(x))), op=_mpi().LAND)

    def reduce_any(self, flag: bool) -> bool:
        return self.comm.allreduce(bool(flag), op=_mpi().LOR)

    def reduce_min(self, value: float) -> float:
        return self.comm.allreduce(value, op=_mpi().MIN)

    def reduce_sum(self, value: Any) -> Any:
        if isinstance(value, np.ndarray):
            out = np.empty_like(value)
            self.comm.Allreduce(np.ascontiguousarray(value), out, op=_mpi().SUM)
            return out
        return self.comm.allreduce(value)

    def reduce_max(self, value: Any) -> Any:
        if isinstance(value, np.ndarray):
            out = np.empty_like(value)
            self.comm.Allreduce(np.ascontiguousarray(value), out, op=_mpi().MAX)
            return out
        return self.comm.allreduce(value, op=_mpi().MAX)

    def gather(self, x: np.ndarray) -> np.ndarray:
        return self.layout.gather(x)

    def gather_records(self, records: dict[str, np.ndarray] | None, order: np.ndarray | None
                       ) -> dict[str, np.ndarray] | None:
        parts = [(r, o) for r, o in self.comm.allgather((records, order)) if r is not None]
        if not parts:
            return None
        place = np.argsort(np.concatenate([o for _, o in parts]), kind="stable")
        return {k: np.concatenate([r[k] for r, _ in parts])[place] for k in parts[0][0]}

    def share(self, value: Any) -> Any:
        return self.comm.bcast(value, root=0)

    def allgather(self, value: Any) -> list[Any]:
        return self.comm.allgather(value)

    def values_at(self, x: np.ndarray, dofs: np.ndarray) -> np.ndarray:
        return self.layout.values_at(x, self.piece.to_global(dofs))

    def gather_lead(self, value: Any) -> list[Any] | None:
        return self.comm.gather(value, root=0)

    def exchange(self, parts: list[Any]) -> list[Any]:
        return self.comm.alltoall(parts)

    def local_signature(self) -> str:
        return hashlib.sha256(np.ascontiguousarray(self.layout.local, dtype=np.int64).tobytes()).hexdigest()

    def owned(self, x: np.ndarray) -> np.ndarray:
        return np.where(self.layout.owned_mask, x, 0.0)

    def agree(self, failure: str | None) -> str | None:
        return next((f for f in self.comm.allgather(failure) if f is not None), None)

    # -- the groups' verdicts over the ranks --------------------------------------------------------
    def event(self) -> tuple[float, float] | None:
        pair = super().event()
        before, after = pair if pair is not None else (math.inf, math.inf)
        before, after = self.reduce_min(before), self.reduce_min(after)
        return None if math.isinf(before) or math.isinf(after) else (before, after)

    def implex_error(self) -> float | None:
        err = super().implex_error()
        worst = -self.reduce_min(-(err if err is not None else -math.inf))
        return None if math.isinf(worst) else worst

    def switch_to_implex(self) -> bool:
        return self.reduce_any(super().switch_to_implex())


def _mpi():
    from mpi4py import MPI

    return MPI
