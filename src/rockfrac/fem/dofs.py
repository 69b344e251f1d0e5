"""Degree-of-freedom numbering: two displacement dofs per node, then element-owned extra dofs."""

from __future__ import annotations

import numpy as np


def node_dofs(cells: np.ndarray) -> np.ndarray:
    """Displacement dofs (n_cells, 2 * nodes_per_cell) of cells given by node indices, (x, y) per node."""
    return np.stack([2 * cells, 2 * cells + 1], axis=-1).reshape(cells.shape[0], -1)
