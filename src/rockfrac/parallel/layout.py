"""Where a rank's dofs live: its owned block of PETSc rows, its ghosts, and the moves between a
rockfrac vector and PETSc's distributed vectors.

A rank keeps rockfrac vectors on its *local* dofs only: those its elements touch or may touch (its
owned dofs and the ghosts around them), numbered 0 .. n_local - 1: the displacements first, then
the extra dofs (multipliers, enrichments), each part in PETSc order. The groups are renumbered
into that numbering (:class:`rockfrac.fem.dofs.LocalNumbering`), so no vector of a rank has the
whole model's length. PETSc's vectors and matrix rows are in the partition's numbering (each rank a
contiguous block, :class:`rockfrac.mesh.partition.Partition`; a rank knows the PETSc index of its
piece's dofs only, :class:`rockfrac.mesh.partition.RankPartition`). ``to_vec`` copies the owned entries
into a PETSc vector; ``from_vec`` fills the local entries from one (owned and ghosts, a scatter);
``sum_local`` adds the ranks' contributions of their elements and returns the sums on the local
entries (the internal forces). The rank's matrix rows (its sparsity pattern) are its local dofs in
PETSc order: ``rows`` gives the local dof of each.
"""

from __future__ import annotations

import numpy as np

from rockfrac.fem.dofs import LocalNumbering
from rockfrac.mesh.partition import RankPartition


def petsc():
    from petsc4py import PETSc

    return PETSc


class Layout:
    """One rank's dofs on the partition: owned (a contiguous PETSc block) and local (owned + ghosts)."""

    def __init__(self, comm, partition: RankPartition, reach: np.ndarray, nodes: np.ndarray):
        """reach: the global dofs this rank's elements touch or may touch (any order, repeats allowed);
        nodes: the coordinates of the rank's piece of the mesh (the owned ones are kept: the AMG's
        rigid-body modes)."""
        PETSc = petsc()
        self.comm, self.rank, self.size = comm, partition.rank, comm.Get_size()
        self.n = partition.n_dofs
        # each rank's first PETSc row; the owned global dofs in PETSc order; global dof -> PETSc index
        self.starts, self.owned, self.petsc_of = partition.numbering()
        self.lo, self.hi = int(self.starts[self.rank]), int(self.starts[self.rank + 1])
        self.n_displacement = partition.dim * partition.n_nodes  # displacements first, then multipliers
        reach = np.unique(np.asarray(reach, dtype=np.int64))
        reach_petsc = self.petsc_of(reach)
        order = np.lexsort((reach_petsc, reach >= self.n_displacement))  # displacements first
        self.local = reach[order]  # the global dof of each local one
        self.n_local_u = int(np.count_nonzero(reach < self.n_displacement))
        self.local_petsc = reach_petsc[order].astype(PETSc.IntType)
        self.numbering = LocalNumbering(self.local)
        self.owned_local, held = self.numbering.local_part(self.owned)  # their local numbers, PETSc order
        if not held.all():  # an owned dof no element of the rank touches: not a partition of this mesh
            raise ValueError(f"rank {self.rank} owns dofs {self.owned[~held][:5].tolist()} that none of its elements "
                             "touches")
        self.owned_mask = np.zeros(self.local.shape[0], dtype=np.bool_)
        self.owned_mask[self.owned_local] = True
        self.rows = np.argsort(self.local_petsc, kind="stable")  # matrix row -> local dof
        self.row_of = np.empty_like(self.rows)  # local dof -> matrix row
        self.row_of[self.rows] = np.arange(self.rows.shape[0])
        self.rows_petsc = self.local_petsc[self.rows]  # each matrix row's PETSc index (ascending)
        blocks = self.owned[::partition.dim] // partition.dim
        # the owned nodes (not multipliers), PETSc order
        self.coordinates = nodes[np.searchsorted(partition.node_ids, blocks[blocks < partition.n_nodes])]
        self.lgmap = PETSc.LGMap().create(self.rows_petsc, comm=comm)
        self._vec = PETSc.Vec().createMPI((self.hi - self.lo, self.n), comm=comm)
        self._seq = PETSc.Vec().createSeq(self.local.shape[0], comm=PETSc.COMM_SELF)
        index = PETSc.IS().createGeneral(self.local_petsc, comm=PETSc.COMM_SELF)
        self._ghosts = PETSc.Scatter().create(self._vec, index, self._seq, None)
        self._modes = None

    def owner(self, petsc_rows: np.ndarray) -> np.ndarray:
        """The rank owning each PETSc row."""
        return np.searchsorted(self.starts, petsc_rows, side="right") - 1

    def new_vec(self):
        """A PETSc vector of the row layout (zero)."""
        v = self._vec.duplicate()
        v.zeroEntries()
        return v

    def to_vec(self, x: np.ndarray, out=None):
        """A PETSc vector holding the owned entries of a local vector x."""
        v = self.new_vec() if out is None else out
        v.getArray()[:] = x[self.owned_local]
        return v

    def from_vec(self, v) -> np.ndarray:
        """A local vector (owned and ghost entries) from the PETSc vector."""
        PETSc = petsc()
        self._ghosts.scatter(v, self._seq, addv=PETSc.InsertMode.INSERT_VALUES, mode=PETSc.ScatterMode.FORWARD)
        return self._seq.getArray().copy()

    def sum_local(self, x: np.ndarray) -> np.ndarray:
        """The sum over the ranks of their local vectors x (their elements' contributions), on the
        local entries."""
        PETSc = petsc()
        v = self._vec
        v.zeroEntries()
        v.setValues(self.local_petsc, x, addv=PETSc.InsertMode.ADD_VALUES)
        v.assemblyBegin()
        v.assemblyEnd()
        return self.from_vec(v)

    @property
    def has_multipliers(self) -> bool:
        """Dofs beyond the displacements (RP multipliers) somewhere in the model (alike on every rank)."""
        return self.n > self.n_displacement

    def rigid_modes(self):
        """The rigid-body modes of the owned nodes (PETSc's orthonormal near-null space) on the
        displacement rows (all the rows without multipliers), made once."""
        if self._modes is None:
            PETSc = petsc()
            dim = self.coordinates.shape[1]
            x = PETSc.Vec().createWithArray(np.ascontiguousarray(self.coordinates.ravel()),
                                            size=(self.coordinates.size, self.n_displacement), bsize=dim,
                                            comm=self.comm)
            self._modes = PETSc.NullSpace().createRigidBody(x)
            x.destroy()
        return self._modes

    def fields(self):
        """PETSc index sets of the owned rows: displacements (in nodal blocks), multipliers."""
        PETSc = petsc()
        rows = self.lo + np.arange(self.hi - self.lo)
        is_u = self.owned < self.n_displacement
        u = PETSc.IS().createGeneral(rows[is_u].astype(PETSc.IntType), comm=self.comm)
        u.setBlockSize(self.coordinates.shape[1])
        lam = PETSc.IS().createGeneral(rows[~is_u].astype(PETSc.IntType), comm=self.comm)
        return u, lam

    def values_at(self, x: np.ndarray, dofs: np.ndarray) -> np.ndarray:
        """A local vector x at global dofs (of the rank's piece of the mesh), each from its owner: one
        scatter of those entries only (a collective call; x is read on the owned entries)."""
        PETSc = petsc()
        dofs = np.asarray(dofs, dtype=np.int64)
        v = self.to_vec(x)
        seq = PETSc.Vec().createSeq(dofs.shape[0], comm=PETSc.COMM_SELF)
        index = PETSc.IS().createGeneral(self.petsc_of(dofs).astype(PETSc.IntType), comm=PETSc.COMM_SELF)
        scatter = PETSc.Scatter().create(v, index, seq, None)
        scatter.scatter(v, seq, addv=PETSc.InsertMode.INSERT_VALUES, mode=PETSc.ScatterMode.FORWARD)
        out = seq.getArray().copy()
        for obj in (scatter, index, seq, v):
            obj.destroy()
        return out

    def gather(self, x: np.ndarray) -> np.ndarray:
        """The whole vector of a local one, in the global numbering, on every rank, each entry from its
        owner (output, tests)."""
        full = np.zeros(self.n)
        full[self.owned] = x[self.owned_local]
        return self.comm.allreduce(full)
