"""Meshes of the standard rock tests, made by Gmsh's Python API (no script file is run) and written
as .msh files a case reads with ``[mesh] kind = "gmsh"``.

- :func:`disc`: the Brazilian disc, loaded over two short arcs (``load_top``, ``load_bottom``),
  with its vertical diameter as an internal curve (``diameter``, where a crack may go);
- :func:`plate_with_hole`: a quarter of a square plate around a borehole, symmetry edges
  ``left`` (x = 0) and ``bottom`` (y = 0), the hole ``hole``, an optional ring region ``near``;
- :func:`notched_beam`: a beam with a central bottom notch for three-point bending, the ligament
  above the notch as an internal curve ``ligament``, point groups at the supports and the load;
- :func:`box`: a structured box of hexahedra (or tetrahedra) with its six faces named (3D loads);
- :func:`cylinder`: the triaxial specimen, tetrahedra, faces ``top``, ``bottom``, ``side``, points
  ``centre_bottom`` and ``rim_bottom`` to hold it still, optionally cut by an inclined ``joint``.

Each 2D one takes an element size and the element type ("quad4": all quadrilaterals by Gmsh's
recombination and subdivision, or "tri3"), and names every group the examples use.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from rockfrac.mesh.gmsh_io import gmsh_session


def _options(h: float, element: str) -> None:
    import gmsh

    if element not in ("quad4", "tri3"):
        raise ValueError(f"element must be 'quad4' or 'tri3', got {element!r}")
    quads = element == "quad4"
    for key, value in {
        "General.NumThreads": 1,  # deterministic
        "Mesh.MeshSizeMax": 2 * h if quads else h,  # the subdivision halves the quads
        "Mesh.MeshSizeMin": 0.0,
        "Mesh.Algorithm": 8 if quads else 6,
        "Mesh.RecombineAll": int(quads),
        "Mesh.RecombinationAlgorithm": 1,
        "Mesh.SubdivisionAlgorithm": int(quads),
        "Mesh.MshFileVersion": 4.1,
    }.items():
        gmsh.option.setNumber(key, value)


def _in_box(dim: int, x0: float, y0: float, x1: float, y1: float) -> list[int]:
    """Entities of ``dim`` inside the box, with a margin above OCC's bounding-box tolerance (relative
    to the model's size, far below any feature of these meshes)."""
    import gmsh

    xmin, ymin, _, xmax, ymax, _ = gmsh.model.getBoundingBox(-1, -1)
    e = 1e-5 * max(xmax - xmin, ymax - ymin)
    return [t for _, t in gmsh.model.getEntitiesInBoundingBox(x0 - e, y0 - e, -e, x1 + e, y1 + e, e, dim=dim)]


def _write(path: str | Path) -> Path:
    import gmsh

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    gmsh.model.mesh.generate(2)
    gmsh.write(str(path))
    return path


def disc(path: str | Path, diameter: float = 0.05, contact_angle: float = math.radians(10.0),
         element_size: float | None = None, element: str = "quad4") -> Path:
    """A disc of ``diameter`` [m] centred at the origin, loaded over two arcs of total angle
    ``contact_angle`` [rad] at the top and bottom: curves load_top, load_bottom, rim (the rest of
    the boundary), diameter (the vertical diameter, internal), points centre and top_point."""
    import gmsh

    r = 0.5 * diameter
    h = element_size or diameter / 20
    a = 0.5 * contact_angle
    with gmsh_session("rockfrac_disc"):
        occ = gmsh.model.occ
        c = occ.addPoint(0, 0, 0)
        angles = [0.5 * math.pi - a, 0.5 * math.pi + a, 1.5 * math.pi - a, 1.5 * math.pi + a]
        pts = [occ.addPoint(r * math.cos(t), r * math.sin(t), 0) for t in angles]
        top, bottom = occ.addPoint(0, r, 0), occ.addPoint(0, -r, 0)
        arcs = [occ.addCircleArc(pts[0], c, top), occ.addCircleArc(top, c, pts[1]),
                occ.addCircleArc(pts[1], c, pts[2]), occ.addCircleArc(pts[2], c, bottom),
                occ.addCircleArc(bottom, c, pts[3]), occ.addCircleArc(pts[3], c, pts[0])]
        loop = occ.addCurveLoop(arcs)
        surface = occ.addPlaneSurface([loop])
        lines = [occ.addLine(bottom, c), occ.addLine(c, top)]  # the centre a vertex of the diameter
        occ.fragment([(2, surface)], [(1, t) for t in lines])
        occ.synchronize()
        gmsh.model.addPhysicalGroup(2, _in_box(2, -r, -r, r, r), name="disc")
        sx = r * math.sin(a)
        gmsh.model.addPhysicalGroup(1, _in_box(1, -sx, r * math.cos(a), sx, r), name="load_top")
        gmsh.model.addPhysicalGroup(1, _in_box(1, -sx, -r, sx, -r * math.cos(a)), name="load_bottom")
        rim = [t for _, t in gmsh.model.getBoundary([(2, s) for s in _in_box(2, -r, -r, r, r)], oriented=False)]
        loaded = set(_in_box(1, -sx, r * math.cos(a), sx, r) + _in_box(1, -sx, -r, sx, -r * math.cos(a)))
        gmsh.model.addPhysicalGroup(1, sorted({abs(t) for t in rim} - loaded), name="rim")
        gmsh.model.addPhysicalGroup(1, _in_box(1, 0, -r, 0, r), name="diameter")
        gmsh.model.addPhysicalGroup(0, _in_box(0, 0, 0, 0, 0), name="centre")
        gmsh.model.addPhysicalGroup(0, _in_box(0, 0, r, 0, r), name="top_point")
        _options(h, element)
        return _write(path)


def plate_with_hole(path: str | Path, radius: float = 0.05, size: float = 1.0, element_size: float | None = None,
                    near_radius: float | None = None, element: str = "quad4", grading: float = 8.0) -> Path:
    """A quarter plate [0, size]^2 without the disc of ``radius`` at the origin: curves hole,
    left (x = 0), bottom (y = 0), right, top; regions rock, and near (r < near_radius) if given.
    Elements of ``element_size`` at the hole, growing ``grading`` times towards the far edges."""
    import gmsh

    h = element_size or radius / 8
    with gmsh_session("rockfrac_hole"):
        occ = gmsh.model.occ
        plate = occ.addRectangle(0, 0, 0, size, size)
        hole = occ.addDisk(0, 0, 0, radius, radius)
        body, _ = occ.cut([(2, plate)], [(2, hole)])
        if near_radius is not None:
            ring = occ.addDisk(0, 0, 0, near_radius, near_radius)
            quarter = occ.addRectangle(0, 0, 0, size, size)
            ring_q, _ = occ.intersect([(2, ring)], [(2, quarter)])
            ring_q, _ = occ.cut(ring_q, [(2, occ.addDisk(0, 0, 0, radius, radius))])  # the hole stays empty
            occ.fragment(body, ring_q)
        occ.synchronize()
        surfaces = _in_box(2, 0, 0, size, size)
        if near_radius is not None:
            near = _in_box(2, 0, 0, near_radius, near_radius)
            gmsh.model.addPhysicalGroup(2, near, name="near")
            gmsh.model.addPhysicalGroup(2, [s for s in surfaces if s not in near], name="rock")
        else:
            gmsh.model.addPhysicalGroup(2, surfaces, name="rock")
        gmsh.model.addPhysicalGroup(1, _in_box(1, 0, 0, radius, radius), name="hole")
        gmsh.model.addPhysicalGroup(1, _in_box(1, 0, 0, 0, size), name="left")
        gmsh.model.addPhysicalGroup(1, _in_box(1, 0, 0, size, 0), name="bottom")
        gmsh.model.addPhysicalGroup(1, _in_box(1, size, 0, size, size), name="right")
        gmsh.model.addPhysicalGroup(1, _in_box(1, 0, size, size, size), name="top")
        field = gmsh.model.mesh.field
        dist = field.add("Distance")
        field.setNumbers(dist, "CurvesList", _in_box(1, 0, 0, radius, radius))
        thr = field.add("Threshold")
        quads = element == "quad4"
        scale = 2.0 if quads else 1.0
        field.setNumber(thr, "InField", dist)
        field.setNumber(thr, "SizeMin", scale * h)
        field.setNumber(thr, "SizeMax", scale * h * grading)
        field.setNumber(thr, "DistMin", 0.5 * radius)
        field.setNumber(thr, "DistMax", 0.5 * size)
        field.setAsBackgroundMesh(thr)
        _options(h * grading, element)
        gmsh.option.setNumber("Mesh.MeshSizeExtendFromBoundary", 0)
        gmsh.option.setNumber("Mesh.MeshSizeFromPoints", 0)
        gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", 0)
        return _write(path)


def notched_beam(path: str | Path, length: float = 0.2, height: float = 0.05, span: float = 0.16,
                 notch_depth: float = 0.015, notch_width: float = 0.002, element_size: float | None = None,
                 element: str = "quad4") -> Path:
    """A beam [0, length] x [0, height] with a bottom notch of ``notch_depth`` and ``notch_width`` at
    its centre: curve ligament (x = length / 2 from the notch tip to the top, internal), curves
    bottom, top; points support_left, support_right (bottom, ``span`` apart), load (top centre)."""
    import gmsh

    h = element_size or height / 20
    xc = 0.5 * length
    with gmsh_session("rockfrac_beam"):
        occ = gmsh.model.occ
        beam = occ.addRectangle(0, 0, 0, length, height)
        slot = occ.addRectangle(xc - 0.5 * notch_width, 0, 0, notch_width, notch_depth)
        body, _ = occ.cut([(2, beam)], [(2, slot)])
        tip = occ.addPoint(xc, notch_depth, 0)
        top = occ.addPoint(xc, height, 0)
        s_left = occ.addPoint(xc - 0.5 * span, 0, 0)
        s_right = occ.addPoint(xc + 0.5 * span, 0, 0)
        line = occ.addLine(tip, top)
        occ.fragment(body, [(1, line), (0, s_left), (0, s_right)])
        occ.synchronize()
        gmsh.model.addPhysicalGroup(2, _in_box(2, 0, 0, length, height), name="beam")
        gmsh.model.addPhysicalGroup(1, _in_box(1, xc, notch_depth, xc, height), name="ligament")
        gmsh.model.addPhysicalGroup(1, _in_box(1, 0, height, length, height), name="top")
        gmsh.model.addPhysicalGroup(0, _in_box(0, xc - 0.5 * span, 0, xc - 0.5 * span, 0), name="support_left")
        gmsh.model.addPhysicalGroup(0, _in_box(0, xc + 0.5 * span, 0, xc + 0.5 * span, 0), name="support_right")
        gmsh.model.addPhysicalGroup(0, _in_box(0, xc, height, xc, height), name="load")
        _options(h, element)
        return _write(path)


def box(path: str | Path, size: tuple[float, float, float] = (1.0, 1.0, 1.0),
        divisions: tuple[int, int, int] = (2, 2, 2), element: str = "hex8", layers: int = 1) -> Path:
    """A structured box [0, lx] x [0, ly] x [0, lz] [m] (region rock), ``divisions`` cells along x,
    y, z (element "hex8"; "tet4": each hexahedron split into tetrahedra by Gmsh); faces left/right
    (x = 0, lx), front/back (y = 0, ly), bottom/top (z = 0, lz), and the edges where two meet, named
    after both (bottom_left, ..., front_left, back_right: z-faces first, then y-faces). ``layers`` > 1
    (dividing divisions[2]): the box is a stack of that many equal slabs, each a volume of its own,
    in regions "even" and "odd" by turns from the base (cohesive surfaces on their boundaries lie on
    every internal plane between slabs); one slab: region "rock"."""
    import gmsh

    if element not in ("hex8", "tet4"):
        raise ValueError(f"element must be 'hex8' or 'tet4', got {element!r}")
    if isinstance(layers, bool) or not isinstance(layers, int) or layers < 1 or divisions[2] % layers:
        raise ValueError(f"layers must be a whole number >= 1 dividing divisions[2] = {divisions[2]}, got {layers!r}")
    lx, ly, lz = size
    nz = layers
    with gmsh_session("rockfrac_box"):
        slabs = [gmsh.model.occ.addBox(0, 0, k * lz / nz, lx, ly, lz / nz) for k in range(nz)]
        if nz > 1:
            gmsh.model.occ.fragment([(3, slabs[0])], [(3, t) for t in slabs[1:]])
        gmsh.model.occ.synchronize()
        for _, c in gmsh.model.getEntities(1):
            x0, y0, z0, x1, y1, z1 = gmsh.model.getBoundingBox(1, c)
            axis = max(range(3), key=lambda i: (x1 - x0, y1 - y0, z1 - z0)[i])
            gmsh.model.mesh.setTransfiniteCurve(c, (divisions[axis] if axis < 2 else divisions[2] // nz) + 1)
        for _, s in gmsh.model.getEntities(2):
            gmsh.model.mesh.setTransfiniteSurface(s)
            if element == "hex8":
                gmsh.model.mesh.setRecombine(2, s)
        volumes = sorted((gmsh.model.getBoundingBox(3, v)[2], v) for _, v in gmsh.model.getEntities(3))
        for _, v in volumes:
            gmsh.model.mesh.setTransfiniteVolume(v)
        if nz == 1:
            gmsh.model.addPhysicalGroup(3, [volumes[0][1]], name="rock")
        else:
            gmsh.model.addPhysicalGroup(3, [v for _, v in volumes[0::2]], name="even")
            gmsh.model.addPhysicalGroup(3, [v for _, v in volumes[1::2]], name="odd")
        e = 1e-3 * min(size)  # OCC pads bounding boxes by its tolerance (~1e-7 m): a margin relative to the box
        for name, axis, at in (("left", 0, 0.0), ("right", 0, lx), ("front", 1, 0.0), ("back", 1, ly),
                               ("bottom", 2, 0.0), ("top", 2, lz)):
            lo = [-e, -e, -e]
            hi = [lx + e, ly + e, lz + e]
            lo[axis], hi[axis] = at - e, at + e
            faces = [t for _, t in gmsh.model.getEntitiesInBoundingBox(*lo, *hi, dim=2)]
            gmsh.model.addPhysicalGroup(2, faces, name=name)
        sides = {"left": (0, 0.0), "right": (0, lx), "front": (1, 0.0), "back": (1, ly), "bottom": (2, 0.0),
                 "top": (2, lz)}
        for one, two in (("bottom", "left"), ("bottom", "right"), ("bottom", "front"), ("bottom", "back"),
                         ("top", "left"), ("top", "right"), ("top", "front"), ("top", "back"),
                         ("front", "left"), ("front", "right"), ("back", "left"), ("back", "right")):
            lo = [-e, -e, -e]
            hi = [lx + e, ly + e, lz + e]
            for axis, at in (sides[one], sides[two]):
                lo[axis], hi[axis] = at - e, at + e
            edges = [t for _, t in gmsh.model.getEntitiesInBoundingBox(*lo, *hi, dim=1)]
            gmsh.model.addPhysicalGroup(1, edges, name=f"{one}_{two}")
        gmsh.option.setNumber("General.NumThreads", 1)
        gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        gmsh.model.mesh.generate(3)
        gmsh.write(str(path))
    return path


def cylinder(path: str | Path, diameter: float = 0.05, height: float = 0.1, element_size: float | None = None,
             joint_dip: float | None = None) -> Path:
    """The triaxial specimen: a cylinder of ``diameter`` and ``height`` [m] along z, base at z = 0,
    axis through the origin, tetrahedra of ``element_size`` (default diameter / 8). Region rock;
    faces top, bottom, side; points centre_bottom (0, 0, 0) and rim_bottom (r, 0, 0). With
    ``joint_dip`` [rad] it is cut by a plane through its centre, dipping at that angle from the
    horizontal towards +x (the face ``joint``, internal, z = H/2 - x tan(dip); the cells on both
    sides conform).

    The disc is triangulated by Gmsh and stacked in layers along z (between the base, the joint
    plane and the top), every prism split into three tetrahedra with the diagonals of its sides
    through their lowest-numbered node (so neighbours conform). All the side's facets are vertical,
    so a uniform lateral pressure with a uniform axial stress is an exact, homogeneous solution, also
    with the joint open or sliding uniformly.
    """
    import gmsh

    r = 0.5 * diameter
    h = element_size or diameter / 8
    if joint_dip is not None and not 0.0 <= joint_dip < math.atan2(height, diameter):
        raise ValueError(f"joint_dip must be in [0, atan(H / D)) = [0, {math.atan2(height, diameter):.4g}) rad "
                         f"so that the joint plane cuts the side only, got {joint_dip!r}")
    with gmsh_session("rockfrac_cylinder_disc"):
        occ = gmsh.model.occ
        disk = occ.addDisk(0, 0, 0, r, r)
        occ.fragment([(2, disk)], [(0, occ.addPoint(0, 0, 0)), (0, occ.addPoint(r, 0, 0))])
        occ.synchronize()
        for key, value in {"General.NumThreads": 1, "Mesh.MeshSizeMax": h, "Mesh.MeshSizeMin": 0.0,
                           "Mesh.Algorithm": 6}.items():
            gmsh.option.setNumber(key, value)
        gmsh.model.mesh.generate(2)
        tags, coords, _ = gmsh.model.mesh.getNodes()
        _, _, tri_nodes = gmsh.model.mesh.getElements(2)
    xy = np.asarray(coords).reshape(-1, 3)[:, :2]
    index = np.empty(int(np.max(tags)) + 1, dtype=np.int64)
    index[np.asarray(tags, dtype=np.int64)] = np.arange(len(tags))
    tri = index[np.asarray(tri_nodes[0], dtype=np.int64)].reshape(-1, 3)
    a, b = xy[tri[:, 1]] - xy[tri[:, 0]], xy[tri[:, 2]] - xy[tri[:, 0]]
    clockwise = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0] < 0
    tri[clockwise] = tri[clockwise][:, [0, 2, 1]]
    z_joint = 0.5 * height - xy[:, 0] * math.tan(joint_dip or 0.0)
    if joint_dip is None:
        fractions = np.linspace(0.0, 1.0, max(1, round(height / h)) + 1)[:, None]
        z = fractions * height * np.ones(len(xy))
        joint_layer = None
    else:
        low = np.linspace(0.0, 1.0, max(1, round(0.5 * height / h)) + 1)[:, None] * z_joint
        up = z_joint + np.linspace(0.0, 1.0, max(1, round(0.5 * height / h)) + 1)[1:, None] * (height - z_joint)
        z = np.vstack([low, up])
        joint_layer = low.shape[0] - 1
    nodes, tets, faces = _layered_prisms(xy, tri, z)
    layers = faces.pop("layer")
    if joint_layer is not None:
        faces["joint"] = layers[joint_layer]
    return write_tets(path, nodes, tets, faces,
                       {"centre_bottom": int(np.argmin(np.linalg.norm(xy, axis=1))),
                        "rim_bottom": int(np.argmin(np.linalg.norm(xy - [r, 0.0], axis=1)))})


def _layered_prisms(xy: np.ndarray, tri: np.ndarray, z: np.ndarray) -> tuple[np.ndarray, np.ndarray, dict]:
    """Nodes (n_layers n2, 3), tetrahedra and faces of a triangulated disc xy (n2, 2), tri (k, 3)
    counter-clockwise, stacked at heights z (n_layers, n2): node k n2 + i is xy[i] at z[k, i]. Faces:
    bottom, top (outward), side (outward), layer: the triangles of every layer (k, 3) by layer."""
    n2, n_layers = len(xy), z.shape[0]
    nodes = np.column_stack([np.tile(xy, (n_layers, 1)), z.ravel()])
    # each prism: bottom triangle rotated to start at its lowest node (same orientation)
    first = np.argmin(tri, axis=1)
    rot = np.stack([tri[np.arange(len(tri)), (first + j) % 3] for j in range(3)], axis=1)
    tets = []
    for k in range(n_layers - 1):
        v0, v1, v2 = (k * n2 + rot[:, j] for j in range(3))
        v3, v4, v5 = v0 + n2, v1 + n2, v2 + n2
        one = (v1 < v2)[:, None]  # the side (v1, v2, v5, v4) split through v1 or through v2
        tets.append(np.where(one, np.stack([v0, v1, v2, v5], 1), np.stack([v0, v1, v2, v4], 1)))
        tets.append(np.where(one, np.stack([v0, v1, v5, v4], 1), np.stack([v0, v4, v2, v5], 1)))
        tets.append(np.stack([v0, v4, v5, v3], 1))
    cells = np.vstack(tets)
    x = nodes[cells]
    vol = np.einsum("ki,ki->k", np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]), x[:, 3] - x[:, 0])
    cells[vol < 0] = cells[vol < 0][:, [0, 2, 1, 3]]
    # the disc's boundary edges, counter-clockwise: the edges of one triangle only
    edges = np.vstack([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]])
    key = np.sort(edges, axis=1)
    _, inverse, count = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    rim = edges[count[inverse.ravel()] == 1]
    side = []
    for k in range(n_layers - 1):
        a0, b0 = k * n2 + rim[:, 0], k * n2 + rim[:, 1]
        a1, b1 = a0 + n2, b0 + n2
        low_a = (a0 < b0)[:, None]  # the diagonal through the lowest node, as in the prisms
        side.append(np.where(low_a, np.stack([a0, b0, b1], 1), np.stack([a0, b0, a1], 1)))
        side.append(np.where(low_a, np.stack([a0, b1, a1], 1), np.stack([b0, b1, a1], 1)))
    layers = [k * n2 + tri for k in range(n_layers)]
    return nodes, cells, {"bottom": layers[0][:, [0, 2, 1]], "top": layers[-1], "side": np.vstack(side),
                          "layer": layers}


def write_tets(path: str | Path, nodes: np.ndarray, tets: np.ndarray, faces: dict, points: dict,
               regions: dict[str, np.ndarray] | None = None) -> Path:
    """Write tetrahedra (each region a physical volume; default one region rock), named triangle
    faces and named single nodes as a Gmsh .msh file."""
    import gmsh

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    regions = regions or {"rock": np.arange(len(tets))}
    with gmsh_session("rockfrac_tets"):
        model = gmsh.model
        tag = 1
        for k, (name, cells) in enumerate(regions.items()):
            model.addDiscreteEntity(3, k + 1)
            if k == 0:
                model.mesh.addNodes(3, 1, np.arange(1, len(nodes) + 1), nodes.ravel())
            model.mesh.addElementsByType(k + 1, 4, np.arange(tag, tag + len(cells)), (tets[cells] + 1).ravel())
            tag += len(cells)
            model.addPhysicalGroup(3, [k + 1], name=name)
        for k, (name, tri) in enumerate(faces.items()):
            model.addDiscreteEntity(2, k + 1)
            model.mesh.addElementsByType(k + 1, 2, np.arange(tag, tag + len(tri)), (tri + 1).ravel())
            tag += len(tri)
            model.addPhysicalGroup(2, [k + 1], name=name)
        for k, (name, node) in enumerate(points.items()):
            model.addDiscreteEntity(0, k + 1)
            model.mesh.addElementsByType(k + 1, 15, [tag], [node + 1])
            tag += 1
            model.addPhysicalGroup(0, [k + 1], name=name)
        gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
        gmsh.write(str(path))
    return path
