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
        divisions: tuple[int, int, int] = (2, 2, 2), element: str = "hex8") -> Path:
    """A structured box [0, lx] x [0, ly] x [0, lz] [m] (region rock), ``divisions`` cells along x,
    y, z (element "hex8"; "tet4": each hexahedron split into tetrahedra by Gmsh); faces left/right
    (x = 0, lx), front/back (y = 0, ly), bottom/top (z = 0, lz)."""
    import gmsh

    if element not in ("hex8", "tet4"):
        raise ValueError(f"element must be 'hex8' or 'tet4', got {element!r}")
    lx, ly, lz = size
    with gmsh_session("rockfrac_box"):
        gmsh.model.occ.addBox(0, 0, 0, lx, ly, lz)
        gmsh.model.occ.synchronize()
        for _, c in gmsh.model.getEntities(1):
            x0, y0, z0, x1, y1, z1 = gmsh.model.getBoundingBox(1, c)
            axis = max(range(3), key=lambda i: (x1 - x0, y1 - y0, z1 - z0)[i])
            gmsh.model.mesh.setTransfiniteCurve(c, divisions[axis] + 1)
        for _, s in gmsh.model.getEntities(2):
            gmsh.model.mesh.setTransfiniteSurface(s)
            if element == "hex8":
                gmsh.model.mesh.setRecombine(2, s)
        gmsh.model.mesh.setTransfiniteVolume(1)
        gmsh.model.addPhysicalGroup(3, [1], name="rock")
        e = 1e-6 * max(size)
        for name, axis, at in (("left", 0, 0.0), ("right", 0, lx), ("front", 1, 0.0), ("back", 1, ly),
                               ("bottom", 2, 0.0), ("top", 2, lz)):
            lo = [-e, -e, -e]
            hi = [lx + e, ly + e, lz + e]
            lo[axis], hi[axis] = at - e, at + e
            faces = [t for _, t in gmsh.model.getEntitiesInBoundingBox(*lo, *hi, dim=2)]
            gmsh.model.addPhysicalGroup(2, faces, name=name)
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
    faces top, bottom, side; points centre_bottom (0, 0, 0) and rim_bottom (r, 0, 0).

    Intact, the cylinder is a triangulated disc extruded in layers (each prism split into three
    tetrahedra), so its faceted side is a vertical prism and a uniform lateral pressure with a
    uniform axial stress is an exact, homogeneous solution. With ``joint_dip`` [rad] it is cut by a
    plane through its centre, dipping at that angle from the horizontal towards +x (the face
    ``joint``, internal; the cells on both sides conform), meshed unstructured."""
    import gmsh

    r = 0.5 * diameter
    h = element_size or diameter / 8
    if joint_dip is not None and not 0.0 <= joint_dip < math.atan2(height, diameter):
        raise ValueError(f"joint_dip must be in [0, atan(H / D)) = [0, {math.atan2(height, diameter):.4g}) rad "
                         f"so that the joint plane cuts the side only, got {joint_dip!r}")
    with gmsh_session("rockfrac_cylinder"):
        occ = gmsh.model.occ
        if joint_dip is None:  # a triangulated disc extruded in layers: every side facet vertical
            disk = occ.addDisk(0, 0, 0, r, r)
            occ.fragment([(2, disk)], [(0, occ.addPoint(0, 0, 0)), (0, occ.addPoint(r, 0, 0))])
            layers = max(1, round(height / h))
            occ.extrude(occ.getEntities(2), 0, 0, height, numElements=[layers], recombine=False)
        else:
            body = [(3, occ.addCylinder(0, 0, 0, 0, 0, height, r))]
            plane = occ.addDisk(0, 0, 0, 2 * diameter, 2 * diameter)
            occ.rotate([(2, plane)], 0, 0, 0, 0, 1, 0, joint_dip)  # about +y: z = -x tan(dip), down towards +x
            occ.translate([(2, plane)], 0, 0, 0.5 * height)
            occ.fragment(body, [(0, occ.addPoint(0, 0, 0)), (0, occ.addPoint(r, 0, 0)), (2, plane)])
        occ.synchronize()
        e = 1e-6 * max(diameter, height)
        inside = gmsh.model.getEntitiesInBoundingBox(-r - e, -r - e, -e, r + e, r + e, height + e, dim=2)
        outside = [t for _, t in gmsh.model.getEntities(2) if (2, t) not in inside]
        if outside:  # the cutting disk beyond the cylinder
            gmsh.model.removeEntities([(2, t) for t in outside], recursive=True)
        volumes = [t for _, t in gmsh.model.getEntities(3)]
        gmsh.model.addPhysicalGroup(3, volumes, name="rock")
        top = [t for _, t in gmsh.model.getEntitiesInBoundingBox(-r - e, -r - e, height - e, r + e, r + e,
                                                                  height + e, dim=2)]
        bottom = [t for _, t in gmsh.model.getEntitiesInBoundingBox(-r - e, -r - e, -e, r + e, r + e, e, dim=2)]
        faces = [abs(t) for v in volumes for _, t in gmsh.model.getBoundary([(3, v)], oriented=False)]
        internal = sorted({t for t in faces if faces.count(t) > 1})  # between two volumes
        side = sorted(set(faces) - set(internal) - set(top) - set(bottom))
        gmsh.model.addPhysicalGroup(2, top, name="top")
        gmsh.model.addPhysicalGroup(2, bottom, name="bottom")
        gmsh.model.addPhysicalGroup(2, side, name="side")
        if joint_dip is not None:
            gmsh.model.addPhysicalGroup(2, internal, name="joint")
        for name, x in (("centre_bottom", 0.0), ("rim_bottom", r)):
            pts = gmsh.model.getEntitiesInBoundingBox(x - e, -e, -e, x + e, e, e, dim=0)
            gmsh.model.addPhysicalGroup(0, [t for _, t in pts], name=name)
        for key, value in {"General.NumThreads": 1, "Mesh.MeshSizeMax": h, "Mesh.MeshSizeMin": 0.0,
                           "Mesh.Algorithm3D": 1, "Mesh.MshFileVersion": 4.1}.items():
            gmsh.option.setNumber(key, value)
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        gmsh.model.mesh.generate(3)
        gmsh.write(str(path))
    return path
