"""Where a rank's dofs live: its owned block of PETSc rows, its ghosts, and the moves between a
rockfrac vector and PETSc's distributed vectors.

A rank keeps rockfrac vectors at full length in rockfrac's dof numbering, valid on its *local*
dofs: those its elements touch (its owned dofs and the ghosts around them); the other entries are
never read. PETSc's vectors and matrix rows are in the partition's numbering (each rank a
contiguous block, :class:`rockfrac.mesh.partition.Partition`). ``to_vec`` copies the owned entries
into a PETSc vector; ``from_vec`` fills the local entries from one (owned and ghosts, a scatter);
``sum_local`` adds the ranks' contributions of their elements and returns the sums on the local
entries (the internal forces).
"""

from __future__ import annotations

import numpy as np

from rockfrac.mesh.partition import Partition


def petsc():
    from petsc4py import PETSc

    return PETSc


class Layout:
    """One rank's dofs on the partition: owned (a contiguous PETSc block) and local (owned + ghosts)."""

    def __init__(self, comm, partition: Partition, rank: int, local: np.ndarray, nodes: np.ndarray):
        """local: the rockfrac dofs this rank's elements touch (sorted or not); nodes: the mesh's
        coordinates (the owned ones are kept: the AMG's rigid-body modes)."""
        PETSc = petsc()
        self.comm, self.rank, self.size = comm, rank, comm.Get_size()
        self.n = partition.n_dofs
        self.new = partition.new_dofs()  # rockfrac dof -> PETSc index
        self.lo, self.hi = partition.owned_range(rank)
        self.owned = partition.owned_dofs(rank)  # rockfrac dofs in PETSc order
        self.starts = np.array([partition.owned_range(r)[0] for r in range(self.size)] + [self.n])
        order = np.argsort(self.new[local], kind="stable")
        self.local = np.asarray(local, dtype=np.int64)[order]
        self.local_petsc = self.new[self.local].astype(PETSc.IntType)
        missing = np.setdiff1d(self.owned, self.local)
        if missing.size:  # an owned dof no element of the rank touches: not a partition of this mesh
            raise ValueError(f"rank {rank} owns dofs {missing[:5].tolist()} that none of its elements touches")
        self.n_displacement = nodes.size  # rockfrac numbers the displacements first, then multipliers
        blocks = self.owned[::partition.dim] // partition.dim
        self.coordinates = nodes[blocks[blocks < nodes.shape[0]]]  # owned nodes (not multipliers), PETSc order
        self.owned_mask = np.zeros(self.n, dtype=np.bool_)
        self.owned_mask[self.owned] = True
        self.lgmap = PETSc.LGMap().create(self.local_petsc, comm=comm)
        self._vec = PETSc.Vec().createMPI((self.hi - self.lo, self.n), comm=comm)
        self._seq = PETSc.Vec().createSeq(self.local.shape[0], comm=PETSc.COMM_SELF)
        index = PETSc.IS().createGeneral(self.local_petsc, comm=PETSc.COMM_SELF)
        self._ghosts = PETSc.Scatter().create(self._vec, index, self._seq, None)
        self._modes = None

    def destroy(self) -> None:
        """Free the PETSc objects (a layout made again after the model's dofs changed)."""
        for obj in (self._ghosts, self._seq, self._vec, self.lgmap, self._modes):
            if obj is not None:
                obj.destroy()

    def owner(self, petsc_rows: np.ndarray) -> np.ndarray:
        """The rank owning each PETSc row."""
        return np.searchsorted(self.starts, petsc_rows, side="right") - 1

    def new_vec(self):
        """A PETSc vector of the row layout (zero)."""
        v = self._vec.duplicate()
        v.zeroEntries()
        return v

    def to_vec(self, x: np.ndarray, out=None):
        """A PETSc vector holding x's owned entries."""
        v = self.new_vec() if out is None else out
        v.getArray()[:] = x[self.owned]
        return v

    def from_vec(self, v) -> np.ndarray:
        """A full-length rockfrac vector, its local entries (owned and ghosts) from the PETSc vector."""
        PETSc = petsc()
        self._ghosts.scatter(v, self._seq, addv=PETSc.InsertMode.INSERT_VALUES, mode=PETSc.ScatterMode.FORWARD)
        out = np.zeros(self.n)
        out[self.local] = self._seq.getArray()
        return out

    def sum_local(self, x: np.ndarray) -> np.ndarray:
        """The sum over the ranks of their vectors x (each nonzero on its local entries), on the
        local entries of a full-length vector."""
        PETSc = petsc()
        v = self._vec
        v.zeroEntries()
        v.setValues(self.local_petsc, x[self.local], addv=PETSc.InsertMode.ADD_VALUES)
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
        """x at any dofs (rockfrac numbering), each from its owner: one scatter of those entries only
        (a collective call; x is read on the owned entries)."""
        PETSc = petsc()
        dofs = np.asarray(dofs, dtype=np.int64)
        v = self.to_vec(x)
        seq = PETSc.Vec().createSeq(dofs.shape[0], comm=PETSc.COMM_SELF)
        index = PETSc.IS().createGeneral(self.new[dofs].astype(PETSc.IntType), comm=PETSc.COMM_SELF)
        scatter = PETSc.Scatter().create(v, index, seq, None)
        scatter.scatter(v, seq, addv=PETSc.InsertMode.INSERT_VALUES, mode=PETSc.ScatterMode.FORWARD)
        out = seq.getArray().copy()
        for obj in (scatter, index, seq, v):
            obj.destroy()
        return out

    def gather(self, x: np.ndarray) -> np.ndarray:
        """The full vector on every rank, each entry from its owner (output, tests)."""
        full = np.zeros(self.n)
        full[self.owned] = x[self.owned]
        return self.comm.allreduce(full)
