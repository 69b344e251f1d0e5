"""Degree-of-freedom numbering: dim displacement dofs per node, then element-owned extra dofs."""

from __future__ import annotations

from typing import Protocol

import numpy as np


def node_dofs(cells: np.ndarray, dim: int = 2) -> np.ndarray:
    """Displacement dofs (n_cells, dim * nodes_per_cell) of cells given by node indices, node by node."""
    return (dim * cells[:, :, None] + np.arange(dim)).reshape(cells.shape[0], cells.shape[1] * dim)


class Numbering(Protocol):
    """An MPI rank's map from the numbering its groups are built in to its local one, and back."""

    @property
    def n(self) -> int: ...

    def local(self, dofs: np.ndarray) -> np.ndarray: ...

    def local_part(self, dofs: np.ndarray) -> tuple[np.ndarray, np.ndarray]: ...

    def global_(self, local: np.ndarray) -> np.ndarray: ...


class LocalNumbering:
    """One MPI rank's dofs numbered 0 .. n - 1 (its local numbering) and their global numbers.

    global_ids: (n,) the global dof of each local one, distinct. :meth:`local` maps global dofs to
    local ones (a KeyError-like ValueError for a dof the rank does not hold), :meth:`local_part`
    keeps those it holds; :meth:`global_` maps back.
    """

    def __init__(self, global_ids: np.ndarray):
        self.global_ids = np.asarray(global_ids, dtype=np.int64)
        self._order = np.argsort(self.global_ids, kind="stable")
        self._sorted = self.global_ids[self._order]

    @property
    def n(self) -> int:
        return int(self.global_ids.shape[0])

    def _find(self, dofs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        dofs = np.asarray(dofs, dtype=np.int64)
        pos = np.minimum(np.searchsorted(self._sorted, dofs), max(self.n - 1, 0))
        hit = self._sorted[pos] == dofs if self.n else np.zeros(dofs.shape, dtype=bool)
        return self._order[pos] if self.n else np.zeros(dofs.shape, dtype=np.int64), hit

    def local(self, dofs: np.ndarray) -> np.ndarray:
        """The local numbers of global dofs (any shape), every one of them held here."""
        local, hit = self._find(dofs)
        if not hit.all():
            missing = np.asarray(dofs)[~hit]
            raise ValueError(f"global dofs {missing[:5].tolist()} are not among this rank's {self.n} local dofs")
        return local

    def local_part(self, dofs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(local numbers of the global dofs held here, where they are among ``dofs`` (a mask))."""
        local, hit = self._find(dofs)
        return local[hit], hit

    def global_(self, local: np.ndarray) -> np.ndarray:
        """The global numbers of local dofs (any shape)."""
        return self.global_ids[np.asarray(local, dtype=np.int64)]


def piece_to_global(dofs: np.ndarray, dim: int, node_ids: np.ndarray) -> np.ndarray:
    """Global dofs of dofs numbered on a piece of the mesh (``node_ids``: the whole mesh's index of
    each of its nodes): a node dof dim p + k is dim node_ids[p] + k, an extra dof stays."""
    dofs = np.asarray(dofs, dtype=np.int64)
    block, comp = np.divmod(dofs, dim)
    node = block < node_ids.shape[0]
    return np.where(node, dim * node_ids[np.where(node, block, 0)] + comp, dofs)


class PieceNumbering:
    """A rank's local numbering of dofs numbered on its piece of the mesh: the piece's node dofs (dim
    times the piece's node index plus the component) and the extra dofs (their global numbers, from
    dim times the whole mesh's node count). They go to global dofs through the whole mesh's index of
    each of the piece's nodes, then to local ones through ``inner``; :meth:`global_` goes back to the
    piece's numbering. On a piece that is the whole mesh, this is ``inner``."""

    def __init__(self, inner: LocalNumbering, dim: int, node_ids: np.ndarray, n_nodes: int):
        self.inner, self.dim, self.node_ids, self.n_nodes = inner, dim, np.asarray(node_ids, np.int64), n_nodes

    @property
    def n(self) -> int:
        return self.inner.n

    def to_global(self, dofs: np.ndarray) -> np.ndarray:
        """Global dofs of the piece's dofs (any shape)."""
        return piece_to_global(dofs, self.dim, self.node_ids)

    def from_global(self, dofs: np.ndarray) -> np.ndarray:
        """The piece's dofs of global ones (of its nodes, or extra)."""
        dofs = np.asarray(dofs, dtype=np.int64)
        block, comp = np.divmod(dofs, self.dim)
        node = block < self.n_nodes
        return np.where(node, self.dim * np.searchsorted(self.node_ids, np.where(node, block, 0)) + comp, dofs)

    def local(self, dofs: np.ndarray) -> np.ndarray:
        return self.inner.local(self.to_global(dofs))

    def local_part(self, dofs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return self.inner.local_part(self.to_global(dofs))

    def global_(self, local: np.ndarray) -> np.ndarray:
        """The piece's numbers of local dofs (any shape)."""
        return self.from_global(self.inner.global_(local))
