"""The Mesh container: nodes, bulk quads, interface cells and named boundary groups."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class Mesh:
    """A 2D mesh; nothing here assumes structure.

    nodes: (n_nodes, 2) coordinates [m].
    quads: (n_quads, 4) counter-clockwise node indices of bilinear quadrilaterals.
    interfaces: (n_if, 4) zero-thickness interface cells, ordered (m0, m1, p0, p1): minus-side
        nodes m0 -> m1 along the tangent t, and the plus-side nodes p0, p1 facing them. The normal
        n points from the minus to the plus side with (t, n) right-handed.
    node_sets: named node index arrays (Dirichlet conditions, reactions).
    edge_sets: named (k, 2) node-pair arrays of boundary edges (pressure loads).
    """

    nodes: np.ndarray
    quads: np.ndarray
    interfaces: np.ndarray = field(default_factory=lambda: np.zeros((0, 4), dtype=np.int64))
    node_sets: dict[str, np.ndarray] = field(default_factory=dict)
    edge_sets: dict[str, np.ndarray] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.nodes = np.ascontiguousarray(self.nodes, dtype=np.float64)
        self.quads = np.ascontiguousarray(self.quads, dtype=np.int64)
        self.interfaces = np.ascontiguousarray(self.interfaces, dtype=np.int64).reshape(-1, 4)

    @property
    def n_nodes(self) -> int:
        return self.nodes.shape[0]

    def check(self) -> list[str]:
        """Return a list of problems (empty if the mesh is consistent)."""
        problems: list[str] = []
        n = self.n_nodes
        for name, cells in (("quads", self.quads), ("interfaces", self.interfaces)):
            if cells.size and (cells.min() < 0 or cells.max() >= n):
                problems.append(f"{name} reference nodes outside 0..{n - 1}")
        if self.quads.size:
            x = self.nodes[self.quads]  # (e, 4, 2)
            # signed area by the shoelace formula; must be positive (counter-clockwise)
            area = 0.5 * np.sum(
                x[:, :, 0] * np.roll(x[:, :, 1], -1, axis=1)
                - np.roll(x[:, :, 0], -1, axis=1) * x[:, :, 1],
                axis=1,
            )
            bad = np.flatnonzero(area <= 0.0)
            if bad.size:
                problems.append(f"quads {bad[:5].tolist()} are inverted or degenerate")
        if self.interfaces.size:
            xm = self.nodes[self.interfaces[:, :2]]
            xp = self.nodes[self.interfaces[:, 2:]]
            lengths = np.linalg.norm(xm[:, 1] - xm[:, 0], axis=1)
            if np.any(lengths <= 0.0):
                problems.append("interfaces with zero length")
            gap = np.abs(xp - xm).max(initial=0.0)
            if gap > 1e-9 * max(1.0, np.abs(self.nodes).max()):
                problems.append("interface node pairs do not coincide in the reference configuration")
        for name, ids in self.node_sets.items():
            if ids.size and (ids.min() < 0 or ids.max() >= n):
                problems.append(f"node set {name!r} references nodes outside 0..{n - 1}")
        return problems
