"""The Mesh container: nodes, bulk cells of one type, interface cells and named groups."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from rockfrac.mesh.geometry import CELL_TYPES, corner_jacobians


@dataclass(frozen=True)
class PlaceInWhole:
    """Where a piece of a mesh sits in the whole one: the whole mesh's index of each of the piece's
    nodes, cells and interface cells (each ascending), the whole mesh's counts, the sides of the
    whole body's outer boundary that belong to the piece's cells (in the piece's node numbering: a
    piece's own boundary also has the sides it shares with the other pieces), the size of each node
    group in the whole mesh, and its bounding box ((2, dim): lowest and highest coordinates [m])."""

    nodes: np.ndarray
    cells: np.ndarray
    interfaces: np.ndarray
    n_nodes: int
    n_cells: int
    n_interfaces: int
    outer: np.ndarray
    node_set_sizes: dict[str, int]
    bounds: np.ndarray


@dataclass
class Mesh:
    """A 2D or 3D mesh; nothing here assumes structure.

    nodes: (n_nodes, dim) coordinates [m].
    cells: (n_cells, n) node indices of the bulk cells, of type ``cell_type`` ("tri3" or "quad4"
        counter-clockwise, "tet4" right-handed, or "hex8" in VTK order: bottom face counter-clockwise
        seen from above, then top).
    interfaces: (n_if, 4) zero-thickness 2D interface cells, ordered (m0, m1, p0, p1): minus-side
        nodes m0 -> m1 along the tangent t, and the plus-side nodes p0, p1 facing them. The normal
        n points from the minus to the plus side with (t, n) right-handed. In 3D (n_if, 6) or
        (n_if, 8): a minus face (m_0 .. m_{k-1}) whose right-hand normal points to the plus side,
        then the plus copies p_j of its nodes (rockfrac.mesh.interfaces_3d).
    node_sets: named node index arrays (Dirichlet conditions, reactions).
    edge_sets: named (k, 2) node-pair arrays of 2D boundary edges, counter-clockwise (pressure loads).
    face_sets: named (k, 4) node arrays of 3D boundary quadrilaterals (hex8 meshes) or (k, 3)
        triangles (tet4 meshes), outward normal by the right-hand rule (pressure loads).
    regions: named cell index arrays (materials); by default one region "bulk" with every cell.
    place: for one MPI rank's piece of a larger mesh (:class:`rockfrac.mesh.piece.Cutter`), where
        the piece sits in it; None for a whole mesh.
    """

    nodes: np.ndarray
    cells: np.ndarray
    cell_type: str = "quad4"
    interfaces: np.ndarray = field(default_factory=lambda: np.zeros((0, 4), dtype=np.int64))
    node_sets: dict[str, np.ndarray] = field(default_factory=dict)
    edge_sets: dict[str, np.ndarray] = field(default_factory=dict)
    face_sets: dict[str, np.ndarray] = field(default_factory=dict)
    regions: dict[str, np.ndarray] = field(default_factory=dict)
    place: PlaceInWhole | None = None

    def __post_init__(self) -> None:
        self.nodes = np.ascontiguousarray(self.nodes, dtype=np.float64)
        self.cells = np.ascontiguousarray(self.cells, dtype=np.int64)
        width = 4 if self.nodes.shape[1] == 2 else 2 * {4: 3, 8: 4}.get(self.cells.shape[1], 3)
        self.interfaces = np.ascontiguousarray(self.interfaces, dtype=np.int64).reshape(-1, width)
        if not self.regions:
            self.regions = {"bulk": np.arange(self.cells.shape[0])}

    @property
    def dim(self) -> int:
        return self.nodes.shape[1]

    @property
    def n_nodes(self) -> int:
        return self.nodes.shape[0]

    @property
    def bounds(self) -> np.ndarray:
        """(2, dim) the lowest and highest coordinates of the (whole) mesh [m]."""
        if self.place is not None:
            return self.place.bounds
        return np.stack([self.nodes.min(axis=0), self.nodes.max(axis=0)])

    @property
    def quads(self) -> np.ndarray:
        """The bulk cells of a quadrilateral mesh."""
        if self.cell_type != "quad4":
            raise AttributeError(f"a {self.cell_type} mesh has no quads")
        return self.cells

    def check(self) -> list[str]:
        """Return a list of problems (empty if the mesh is consistent)."""
        problems: list[str] = []
        n = self.n_nodes
        if self.cell_type not in CELL_TYPES:
            return [f"unknown cell type {self.cell_type!r}; known: {sorted(CELL_TYPES)}"]
        dim, corners = CELL_TYPES[self.cell_type]
        if self.dim != dim or self.cells.shape[1] != corners.shape[0]:
            return [f"{self.cell_type} cells need {corners.shape[0]} nodes in {dim}D, got "
                    f"{self.cells.shape[1]} nodes in {self.dim}D"]
        for name, cells in (("cells", self.cells), ("interfaces", self.interfaces)):
            if cells.size and (cells.min() < 0 or cells.max() >= n):
                problems.append(f"{name} reference nodes outside 0..{n - 1}")
        if problems:
            return problems
        if self.cells.size:
            bad = np.flatnonzero((corner_jacobians(self.nodes, self.cells, self.cell_type) <= 0.0).any(axis=1))
            if bad.size:
                problems.append(f"cells {bad[:5].tolist()} are inverted or degenerate (det J <= 0)")
        if self.interfaces.size:
            half = self.interfaces.shape[1] // 2
            xm = self.nodes[self.interfaces[:, :half]]
            xp = self.nodes[self.interfaces[:, half:]]
            if self.dim == 2:
                size = np.linalg.norm(xm[:, 1] - xm[:, 0], axis=1)
            else:
                size = np.linalg.norm(np.cross(xm[:, 1] - xm[:, 0], xm[:, -1] - xm[:, 0]), axis=1)
            if np.any(size <= 0.0):
                problems.append(f"interfaces with zero {'length' if self.dim == 2 else 'area'}")
            gap = np.abs(xp - xm).max(initial=0.0)
            if gap > 1e-9 * max(1.0, np.abs(self.nodes).max()):
                problems.append("interface node pairs do not coincide in the reference configuration")
        for kind, sets in (("node set", self.node_sets), ("region", self.regions)):
            limit = n if kind == "node set" else self.cells.shape[0]
            for name, ids in sets.items():
                if ids.size and (ids.min() < 0 or ids.max() >= limit):
                    problems.append(f"{kind} {name!r} references entries outside 0..{limit - 1}")
        return problems
