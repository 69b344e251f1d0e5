"""Degree-of-freedom numbering: dim displacement dofs per node, then element-owned extra dofs."""

from __future__ import annotations

import numpy as np


def node_dofs(cells: np.ndarray, dim: int = 2) -> np.ndarray:
    """Displacement dofs (n_cells, dim * nodes_per_cell) of cells given by node indices, node by node."""
    return (dim * cells[:, :, None] + np.arange(dim)).reshape(cells.shape[0], cells.shape[1] * dim)


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
