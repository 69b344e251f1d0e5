"""The paper's specimen (Sect. 7, PAPER_NOTES): a W x H plane-strain block, in 2D cut by a straight
crack through its centre, or in 3D a block of hexahedra of some thickness (the EDE case), which a
generated 3D block also uses, as hexahedra or split into tetrahedra."""

from __future__ import annotations

import itertools
import math

import numpy as np

from rockfrac.mesh.mesh import Mesh
from rockfrac.mesh.topology import boundary_faces

_CORNERS = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)]  # VTK hex8
# the six tetrahedra of a hexahedron around its diagonal 0-6 (Kuhn): the edge paths 0 -> 6, one per axis order
KUHN = np.array([[_CORNERS.index(tuple(np.sum(np.eye(3, dtype=int)[list(order[:k])], axis=0)))
                  for k in range(4)] for order in itertools.permutations(range(3))])


def _block(corners: np.ndarray, nx: int, ny: int, offset: int) -> tuple[np.ndarray, np.ndarray]:
    """Bilinearly mapped nx x ny quad grid of a convex quadrilateral (corners counter-clockwise)."""
    xi, eta = np.meshgrid(np.linspace(0.0, 1.0, nx + 1), np.linspace(0.0, 1.0, ny + 1))
    n = np.stack(
        [(1 - xi) * (1 - eta), xi * (1 - eta), xi * eta, (1 - xi) * eta], axis=-1
    )  # (ny+1, nx+1, 4)
    nodes = (n @ corners).reshape(-1, 2)
    ids = np.arange((nx + 1) * (ny + 1)).reshape(ny + 1, nx + 1) + offset
    quads = np.stack(
        [ids[:-1, :-1], ids[:-1, 1:], ids[1:, 1:], ids[1:, :-1]], axis=-1
    ).reshape(-1, 4)
    return nodes, quads


def crack_ends(width: float, height: float, angle: float) -> tuple[float, float]:
    """Heights [m] where a crack through the centre at ``angle`` (rad from horizontal) meets x=0, x=W."""
    rise = 0.5 * width * math.tan(angle)
    return 0.5 * height - rise, 0.5 * height + rise


def cracked_specimen(
    width: float = 0.04,
    height: float = 0.08,
    angle: float = math.radians(60.0),
    nx: int = 1,
    ny: int = 1,
    crack: bool = True,
) -> Mesh:
    """Specimen with a crack through its centre at ``angle`` from horizontal (PAPER_NOTES, Sect. 7).

    Each block (below and above the crack) is an ``nx`` x ``ny`` grid; the crack carries ``nx``
    interface cells with the normal pointing up (lower block = minus side); node sets bottom, top,
    left, right, bottom_left and the crack's faces crack_minus, crack_plus. With ``crack=False``
    the mesh is the uncracked block, a plain ``nx`` x ``ny`` grid.
    """
    if not crack:
        nodes, quads = _block(np.array([[0.0, 0.0], [width, 0.0], [width, height], [0.0, height]]), nx, ny, 0)
        return Mesh(nodes=nodes, cells=quads, cell_type="quad4", **_boundary_groups(nodes, quads, width, height))
    if not (-0.5 * math.pi < angle < 0.5 * math.pi):
        raise ValueError("crack angle must lie strictly between -pi/2 and pi/2 rad")
    y_left, y_right = crack_ends(width, height, angle)
    if not (0.0 < y_left < height and 0.0 < y_right < height):
        raise ValueError(
            f"a crack at {math.degrees(angle):.2f} deg through the centre of a {width} x {height} m "
            "specimen must cut its left and right edges; lower the angle or raise the height"
        )
    lower = np.array([[0.0, 0.0], [width, 0.0], [width, y_right], [0.0, y_left]])
    upper = np.array([[0.0, y_left], [width, y_right], [width, height], [0.0, height]])
    n_lower = (nx + 1) * (ny + 1)
    xl, ql = _block(lower, nx, ny, 0)
    xu, qu = _block(upper, nx, ny, n_lower)
    nodes = np.vstack([xl, xu])
    quads = np.vstack([ql, qu])
    crack_minus = np.arange(ny * (nx + 1), n_lower)  # top row of the lower block
    crack_plus = n_lower + np.arange(nx + 1)  # bottom row of the upper block
    interfaces = np.stack([crack_minus[:-1], crack_minus[1:], crack_plus[:-1], crack_plus[1:]], axis=-1)
    groups = _boundary_groups(nodes, quads, width, height)
    groups["node_sets"].update(crack_minus=crack_minus, crack_plus=crack_plus)  # the crack's two faces
    return Mesh(nodes=nodes, cells=quads, cell_type="quad4", interfaces=interfaces, **groups)


def _boundary_groups(nodes: np.ndarray, quads: np.ndarray, width: float, height: float) -> dict:
    """Node and edge sets of the rectangle's sides, found geometrically."""
    tol = 1e-9 * max(width, height)
    x, y = nodes[:, 0], nodes[:, 1]
    sides = {
        "bottom": np.abs(y) < tol,
        "top": np.abs(y - height) < tol,
        "left": np.abs(x) < tol,
        "right": np.abs(x - width) < tol,
    }
    node_sets = {name: np.flatnonzero(mask) for name, mask in sides.items()}
    node_sets["bottom_left"] = np.flatnonzero(sides["bottom"] & sides["left"])
    edges = np.stack([quads, np.roll(quads, -1, axis=1)], axis=-1).reshape(-1, 2)
    edge_sets = {name: edges[mask[edges].all(axis=1)] for name, mask in sides.items()}
    return {"node_sets": node_sets, "edge_sets": edge_sets}


def hex_specimen(width: float = 0.04, height: float = 0.08, thickness: float = 0.08,
                 nx: int = 1, ny: int = 1, nz: int = 1,
                 inclusion: tuple[float, float, float, float] | None = None) -> Mesh:
    """W x H x T block of nx x ny x nz trilinear hexahedra (x across, y up, z out of plane).

    Node sets: bottom, top, left, right, back (z = 0), front (z = T), bottom_left (the line
    y = 0, x = 0); face sets left, right (outward normals -x, +x) for the confining pressure.
    Regions: "bulk", and with ``inclusion`` = (x0, y0, x1, y1) [m] "weak", the cells whose centroid
    lies in that box (through the thickness).
    """
    xs, ys, zs = (np.linspace(0.0, L, n + 1) for L, n in ((width, nx), (height, ny), (thickness, nz)))
    z, y, x = np.meshgrid(zs, ys, xs, indexing="ij")
    nodes = np.column_stack([x.ravel(), y.ravel(), z.ravel()])
    ids = np.arange(nodes.shape[0]).reshape(nz + 1, ny + 1, nx + 1)
    c = ids[:-1, :-1, :-1], ids[:-1, :-1, 1:], ids[:-1, 1:, 1:], ids[:-1, 1:, :-1]
    top = tuple(ids[1:, j0, i0] for j0, i0 in ((slice(None, -1), slice(None, -1)), (slice(None, -1), slice(1, None)),
                                                (slice(1, None), slice(1, None)), (slice(1, None), slice(None, -1))))
    # VTK hexahedron: (x, y) counter-clockwise at z, then the same above; here "up" is +z
    cells = np.stack([*c, *top], axis=-1).reshape(-1, 8)
    tol = 1e-9 * max(width, height, thickness)
    X, Y, Z = nodes.T
    sides = {"bottom": np.abs(Y) < tol, "top": np.abs(Y - height) < tol, "left": np.abs(X) < tol,
             "right": np.abs(X - width) < tol, "back": np.abs(Z) < tol, "front": np.abs(Z - thickness) < tol}
    node_sets = {k: np.flatnonzero(v) for k, v in sides.items()}
    node_sets["bottom_left"] = np.flatnonzero(sides["bottom"] & sides["left"])
    # faces at x = 0 and x = W, ordered so that (x1 - x0) x (x3 - x0) points outward
    left = np.stack([ids[:-1, :-1, 0], ids[1:, :-1, 0], ids[1:, 1:, 0], ids[:-1, 1:, 0]], axis=-1).reshape(-1, 4)
    right = np.stack([ids[:-1, :-1, -1], ids[:-1, 1:, -1], ids[1:, 1:, -1], ids[1:, :-1, -1]], axis=-1).reshape(-1, 4)
    regions = {}
    if inclusion is not None:
        x0, y0, x1, y1 = inclusion
        c = nodes[cells].mean(axis=1)
        inside = (c[:, 0] >= x0) & (c[:, 0] <= x1) & (c[:, 1] >= y0) & (c[:, 1] <= y1)
        if not inside.any():
            raise ValueError(f"the inclusion {tuple(inclusion)} holds no cell centroid; enlarge it or refine the grid")
        regions = {"weak": np.flatnonzero(inside), "bulk": np.flatnonzero(~inside)}
    return Mesh(nodes=nodes, cells=cells, cell_type="hex8", node_sets=node_sets,
                face_sets={"left": left, "right": right}, regions=regions)


def split_into_tets(mesh: Mesh) -> Mesh:
    """The hexahedra of a structured grid (every cell's local axes along x, y, z) each split into six
    tetrahedra around its diagonal 0-6, which makes the tetrahedra conforming; hexahedron k becomes
    tetrahedra 6k..6k+5 (regions follow), node sets are kept, face sets become the triangles on them."""
    if mesh.cell_type != "hex8":
        raise ValueError(f"split_into_tets takes a hex8 mesh, not {mesh.cell_type}")
    cells = mesh.cells[:, KUHN].reshape(-1, 4)
    x = mesh.nodes[cells]
    volume = np.einsum("ki,ki->k", np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]), x[:, 3] - x[:, 0])
    cells[volume < 0] = cells[volume < 0][:, [0, 2, 1, 3]]  # right-handed
    tets = Mesh(nodes=mesh.nodes, cells=cells, cell_type="tet4", node_sets=dict(mesh.node_sets))
    faces = boundary_faces(tets)
    on = {}
    for name, quads in mesh.face_sets.items():
        inside = np.zeros(mesh.nodes.shape[0], bool)
        inside[quads.ravel()] = True
        on[name] = faces[inside[faces].all(axis=1)]
    six = np.arange(6)
    regions = {k: (6 * v[:, None] + six).ravel() for k, v in mesh.regions.items()}
    return Mesh(nodes=mesh.nodes, cells=cells, cell_type="tet4", node_sets=dict(mesh.node_sets),
                face_sets=on, regions=regions)
