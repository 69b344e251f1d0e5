"""Heterogeneous plane-strain specimens: stiff circular grains in a softer matrix (meshed by Gmsh),
and a structured block with a weak rectangular inclusion (no Gmsh).

Both carry the specimen's boundary groups: node sets bottom, top, left, right, bottom_left and
edge sets bottom, top, left, right (counter-clockwise around the body).

Example::

    mesh = grain_specimen(n_grains=60, seed=1)          # regions "grains" and "matrix"
    write_grain_msh("grains.msh", n_grains=60, seed=1)  # the same mesh, as a Gmsh file
    band = block_with_inclusion(0.04, 0.08, 20, 40, (0.0, 0.035, 0.04, 0.045))  # "weak", "bulk"
"""

from __future__ import annotations

import inspect
import math
from pathlib import Path
from typing import Literal

import numpy as np

from rockfrac.mesh.gmsh_io import boundary_edges, gmsh_session, mesh_from_model
from rockfrac.mesh.mesh import Mesh

__all__ = ["block_with_inclusion", "grain_specimen", "place_grains", "write_grain_msh"]

Element = Literal["quad4", "tri3"]
SIDES = ("bottom", "top", "left", "right")


def place_grains(width: float = 0.04, height: float = 0.08, n_grains: int = 60,
                 radius: tuple[float, float] = (0.0015, 0.003), *, min_gap: float | None = None,
                 seed: int = 0, attempts: int = 20000) -> np.ndarray:
    """Non-overlapping circles (n_grains, 3) = (x, y, r) inside the W x H rectangle [m].

    Radii are drawn uniformly in ``radius`` by ``numpy.random.default_rng(seed)`` and placed
    largest first by rejection sampling (up to ``attempts`` uniform candidate centres each), keeping
    at least ``min_gap`` (default radius[0] / 4) between grains and from the rectangle's sides.
    Raises ValueError if a grain finds no room.
    """
    r_min, r_max = radius
    gap = 0.25 * r_min if min_gap is None else min_gap
    if not (width > 0 and height > 0 and 0 < r_min <= r_max and gap >= 0 and n_grains >= 0):
        raise ValueError("need width, height > 0, 0 < radius[0] <= radius[1], min_gap >= 0 and "
                         "n_grains >= 0")
    if 2 * (r_max + gap) > min(width, height):
        raise ValueError(f"a grain of radius {r_max} m with a gap of {gap} m does not fit in "
                         f"{width} x {height} m")
    rng = np.random.default_rng(seed)
    radii = np.sort(rng.uniform(r_min, r_max, n_grains))[::-1]
    placed = np.zeros((0, 3))
    batch = 256
    for i, r in enumerate(radii):
        for _ in range(max(1, attempts // batch)):
            lo, hi = [r + gap, r + gap], [width - r - gap, height - r - gap]
            c = rng.uniform(lo, hi, size=(batch, 2))  # candidate centres
            d = np.linalg.norm(c[:, None, :] - placed[None, :, :2], axis=2)  # (batch, placed)
            ok = np.flatnonzero((d >= placed[:, 2] + r + gap).all(axis=1))
            if ok.size:
                placed = np.vstack([placed, [*c[ok[0]], r]])
                break
        else:
            frac = np.pi * np.sum(placed[:, 2] ** 2) / (width * height)
            raise ValueError(f"placed only {i} of {n_grains} grains (grain area fraction "
                             f"{frac:.0%}); lower n_grains, the radii or min_gap")
    return placed


def grain_specimen(width: float = 0.04, height: float = 0.08, n_grains: int = 60,
                   radius: tuple[float, float] = (0.0015, 0.003), *, min_gap: float | None = None,
                   seed: int = 0, element_size: float | None = None, element: Element = "quad4",
                   points_per_circle: int = 24) -> Mesh:
    """A W x H plane-strain specimen with circular grains (see :func:`place_grains`) meshed by Gmsh.

    The mesh is conforming across the grain boundaries (OCC boolean fragments). Regions "grains"
    and "matrix"; boundary groups as the module says. element: "tri3" (Frontal-Delaunay) or "quad4"
    (all quads: recombination of a mesh twice as coarse, then every element split into quads).
    element_size [m] (default radius[0] / 2) is the largest element; circles get at least
    ``points_per_circle`` nodes (at 24 the meshed grain area is within 1.2 % of the circles').
    Deterministic for a seed.
    """
    with gmsh_session("rockfrac_grains"):
        _grain_model(width, height, n_grains, radius, min_gap, seed, element_size, element,
                     points_per_circle)
        mesh = mesh_from_model(dim=2, source=f"grain specimen (seed {seed})")
    if mesh.cell_type != element:
        raise RuntimeError(f"Gmsh made {mesh.cell_type} cells where {element} were asked for")
    return mesh


def write_grain_msh(path: str | Path, **kwargs) -> Path:
    """Write the mesh :func:`grain_specimen` makes (same keyword arguments) as a Gmsh .msh 4.1
    file, with its physical groups; :func:`rockfrac.mesh.gmsh_io.read_mesh` reads it back."""
    import gmsh

    args = inspect.signature(grain_specimen).bind(**kwargs)
    args.apply_defaults()
    path = Path(path)
    with gmsh_session("rockfrac_grains"):
        _grain_model(**args.arguments)
        gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
        gmsh.write(str(path))
    return path


def _grain_model(width, height, n_grains, radius, min_gap, seed, element_size, element,
                 points_per_circle) -> None:
    """Build and mesh the grain specimen in Gmsh's current model."""
    import gmsh

    if element not in ("quad4", "tri3"):
        raise ValueError(f"element must be 'quad4' or 'tri3', got {element!r}")
    h = 0.5 * radius[0] if element_size is None else element_size
    if not (h > 0 and points_per_circle >= 8):
        raise ValueError("element_size must be > 0 and points_per_circle >= 8")
    grains = place_grains(width, height, n_grains, radius, min_gap=min_gap, seed=seed)
    occ = gmsh.model.occ
    rect = occ.addRectangle(0.0, 0.0, 0.0, width, height)
    disks = [occ.addDisk(x, y, 0.0, r, r) for x, y, r in grains]
    if disks:
        _, pieces = occ.fragment([(2, rect)], [(2, d) for d in disks])
        grain_tags = [t for p in pieces[1:] for _, t in p]
        matrix = [t for _, t in pieces[0] if t not in set(grain_tags)]
    else:
        grain_tags, matrix = [], [rect]
    occ.synchronize()
    if grain_tags:
        gmsh.model.addPhysicalGroup(2, grain_tags, name="grains")
    gmsh.model.addPhysicalGroup(2, matrix, name="matrix")
    _boundary_groups(width, height)
    quads = element == "quad4"
    for key, value in {
        "General.NumThreads": 1,  # deterministic
        "Mesh.MeshSizeMax": 2 * h if quads else h,  # the subdivision halves the quads
        "Mesh.MeshSizeFromCurvature": math.ceil(points_per_circle / (2 if quads else 1)),
        "Mesh.Algorithm": 8 if quads else 6,  # Frontal-Delaunay (for quads)
        "Mesh.RecombineAll": int(quads),
        "Mesh.RecombinationAlgorithm": 1,  # blossom
        "Mesh.SubdivisionAlgorithm": int(quads),  # all quads
    }.items():
        gmsh.option.setNumber(key, value)
    gmsh.model.mesh.generate(2)


def _boundary_groups(width: float, height: float) -> None:
    """Physical curves bottom, top, left, right and the point bottom_left, found by bounding box."""
    import gmsh

    e = 1e-3 * min(width, height)  # well above OCC's tolerance; a circle's box never fits
    boxes = {"bottom": (-e, -e, width + e, e), "top": (-e, height - e, width + e, height + e),
             "left": (-e, -e, e, height + e), "right": (width - e, -e, width + e, height + e)}
    for name, (x0, y0, x1, y1) in boxes.items():
        curves = [t for _, t in gmsh.model.getEntitiesInBoundingBox(x0, y0, -e, x1, y1, e, dim=1)]
        if len(curves) != 1:
            raise RuntimeError(f"found {len(curves)} curves on the {name} side, expected 1")
        gmsh.model.addPhysicalGroup(1, curves, name=name)
    corner = [t for _, t in gmsh.model.getEntitiesInBoundingBox(-e, -e, -e, e, e, e, dim=0)]
    gmsh.model.addPhysicalGroup(0, corner, name="bottom_left")


def block_with_inclusion(width: float, height: float, nx: int, ny: int,
                         inclusion: tuple[float, float, float, float] | None = None,
                         *, element: Element = "quad4") -> Mesh:
    """A W x H block of nx x ny quads (or each split into two triangles, element="tri3").

    Regions: "weak", the cells whose centroid lies in the box inclusion = (x0, y0, x1, y1) [m],
    and "bulk", the others (only "bulk" without an inclusion). Boundary groups as the module says.
    """
    if element not in ("quad4", "tri3"):
        raise ValueError(f"element must be 'quad4' or 'tri3', got {element!r}")
    if not (width > 0 and height > 0 and nx >= 1 and ny >= 1):
        raise ValueError("need width, height > 0 and nx, ny >= 1")
    x, y = np.meshgrid(np.linspace(0.0, width, nx + 1), np.linspace(0.0, height, ny + 1))
    nodes = np.column_stack([x.ravel(), y.ravel()])
    ids = np.arange((nx + 1) * (ny + 1)).reshape(ny + 1, nx + 1)
    corners = [ids[:-1, :-1], ids[:-1, 1:], ids[1:, 1:], ids[1:, :-1]]  # counter-clockwise
    cells = np.stack(corners, axis=-1).reshape(-1, 4)
    if element == "tri3":
        cells = np.stack([cells[:, [0, 1, 2]], cells[:, [0, 2, 3]]], axis=1).reshape(-1, 3)
    regions = {"bulk": np.arange(len(cells))}
    if inclusion is not None:
        x0, y0, x1, y1 = inclusion
        c = nodes[cells].mean(axis=1)
        inside = (c[:, 0] >= x0) & (c[:, 0] <= x1) & (c[:, 1] >= y0) & (c[:, 1] <= y1)
        if not inside.any():
            raise ValueError(f"the inclusion {tuple(inclusion)} holds no cell centroid; enlarge it "
                             "or refine the grid")
        regions = {"weak": np.flatnonzero(inside), "bulk": np.flatnonzero(~inside)}
    mesh = Mesh(nodes=nodes, cells=cells, cell_type=element, regions=regions)
    node_sets, edge_sets = rectangle_groups(mesh, width, height)
    mesh.node_sets.update(node_sets)
    mesh.edge_sets.update(edge_sets)
    return mesh


def rectangle_groups(mesh: Mesh, width: float, height: float) -> tuple[dict, dict]:
    """Node sets (bottom, top, left, right, bottom_left) and counter-clockwise edge sets (bottom,
    top, left, right) of a 2D mesh filling the rectangle [0, W] x [0, H], found geometrically."""
    tol = 1e-9 * max(width, height)
    x, y = mesh.nodes[:, 0], mesh.nodes[:, 1]
    on = {"bottom": np.abs(y) < tol, "top": np.abs(y - height) < tol,
          "left": np.abs(x) < tol, "right": np.abs(x - width) < tol}
    node_sets = {name: np.flatnonzero(m) for name, m in on.items()}
    node_sets["bottom_left"] = np.flatnonzero(on["bottom"] & on["left"])
    edges = boundary_edges(mesh)
    edge_sets = {name: edges[m[edges].all(axis=1)] for name, m in on.items()}
    return node_sets, edge_sets
