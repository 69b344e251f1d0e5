"""Degree-of-freedom numbering: dim displacement dofs per node, then element-owned extra dofs."""

from __future__ import annotations

import numpy as np


def node_dofs(cells: np.ndarray, dim: int = 2) -> np.ndarray:
    """Displacement dofs (n_cells, dim * nodes_per_cell) of cells given by node indices, node by node."""
    return (dim * cells[:, :, None] + np.arange(dim)).reshape(cells.shape[0], cells.shape[1] * dim)
