"""The mesh of a case: generated or read, checked, and split where cohesive surfaces go."""

from __future__ import annotations

from typing import Literal

import numpy as np

from rockfrac.case.messages import require
from rockfrac.case.cohesive_section import Placement
from rockfrac.case.mesh_section import ElementType, MeshKind
from rockfrac.case.schema import Case
from rockfrac.errors import CaseError
from rockfrac.mesh import Mesh, cracked_specimen, hex_specimen
from rockfrac.mesh.specimen import split_into_tets
from rockfrac.values import given


def plane_element(name: str) -> Literal["quad4", "tri3"]:
    """A 2D element type name, as the generators take it."""
    if name not in ("quad4", "tri3"):
        raise CaseError(f"[mesh] element: {name!r} is not a 2D element (quad4 or tri3)")
    return "quad4" if name == "quad4" else "tri3"


def mean_cell_size(mesh: Mesh) -> float:
    """sqrt of the mean cell area (2D), cube root of the mean cell volume (3D) [m]."""
    if mesh.dim == 3:
        from rockfrac.fem.kinematics import element_gradients
        from rockfrac.fem.reference import ELEMENTS

        _, wdet = element_gradients(mesh.nodes[mesh.cells], ELEMENTS[mesh.cell_type])
        return float(np.cbrt(wdet.sum(axis=1).mean()))
    x = mesh.nodes[mesh.cells][..., :2]
    area = 0.5 * np.abs(np.sum(x[:, :, 0] * np.roll(x[:, :, 1], -1, 1) - np.roll(x[:, :, 0], -1, 1) * x[:, :, 1], 1))
    return float(np.sqrt(area.mean()))


def make_mesh(case: Case, path: str = "<case>") -> Mesh:
    """The bulk mesh of the case (before any cohesive insertion), checked."""
    m = case.mesh.resolved()
    try:
        if m.kind is MeshKind.gmsh:
            from rockfrac.mesh.gmsh_io import read_mesh

            try:
                mesh = read_mesh(given(m.file, "[mesh] file"), dim=None)
            except CaseError as err:
                raise CaseError(f"{path}: [mesh] file: {err}") from None
        elif m.kind is MeshKind.grains:
            from rockfrac.mesh.grains import grain_specimen

            mesh = grain_specimen(m.width, m.height, n_grains=given(m.n_grains),
                                  radius=(given(m.radius_min), given(m.radius_max)), seed=given(m.seed),
                                  element_size=m.element_size, element=plane_element(m.element.value),
                                  points_per_circle=given(m.points_per_circle))
        elif m.kind is MeshKind.block and m.element.solid:
            box = None if m.inclusion is None else (m.inclusion[0], m.inclusion[1], m.inclusion[2], m.inclusion[3])
            mesh = hex_specimen(m.width, m.height, given(m.thickness), given(m.nx), given(m.ny), given(m.nz),
                                inclusion=box)
            if m.element is ElementType.tet4:
                mesh = split_into_tets(mesh)
        elif m.kind is MeshKind.block:
            from rockfrac.mesh.grains import block_with_inclusion

            box = None if m.inclusion is None else (m.inclusion[0], m.inclusion[1], m.inclusion[2], m.inclusion[3])
            mesh = block_with_inclusion(m.width, m.height, given(m.nx), given(m.ny), inclusion=box,
                                        element=plane_element(m.element.value))
        elif m.element is ElementType.hex8:
            mesh = hex_specimen(m.width, m.height, given(m.thickness), given(m.nx), given(m.ny), given(m.nz))
        else:
            try:
                mesh = cracked_specimen(m.width, m.height, m.crack_angle or 0.0, given(m.nx), given(m.ny),
                                        crack=bool(m.crack))
            except ValueError as err:
                raise CaseError(f"{path}: [mesh] crack_angle: {err}") from None
    except CaseError:
        raise
    except (ValueError, RuntimeError) as err:
        raise CaseError(f"{path}: [mesh]: {err}") from None
    problems = mesh.check()
    if problems:
        raise CaseError(f"{path}: [mesh]: " + "; ".join(problems))
    return mesh


def insert_cohesive(case: Case, mesh: Mesh, path: str) -> tuple[Mesh, list[np.ndarray]]:
    """Split the mesh along every cohesive set's edges (faces in 3D); returns the new mesh and each
    set's interface cells."""
    sets = case.cohesive_sets
    if not sets:
        return mesh, []
    if sets[0].where is Placement.crack:  # the specimen carries its crack already
        return mesh, [np.arange(mesh.interfaces.shape[0])]
    from rockfrac.mesh import interfaces as itf
    from rockfrac.mesh import interfaces_3d as i3

    three_d = mesh.dim == 3
    side = "face" if three_d else "edge"
    pair_cells = (i3.internal_faces(mesh) if three_d else itf.internal_edges(mesh)).cells
    chosen, minus = [], []
    for k, c in enumerate(sets):
        key = f"[cohesive{'' if len(sets) == 1 else f' {k + 1}'}]"
        regions = c.regions or []
        if c.where in (Placement.between, Placement.within):
            require(regions, mesh.regions, "region", f"{key} regions", path)
        if c.where is Placement.between:
            mask = (i3.faces_between if three_d else itf.edges_between)(mesh, regions[0], regions[1])
        elif c.where is Placement.within:
            mask = (i3.faces_within if three_d else itf.edges_within)(mesh, regions[0])
        elif c.where is Placement.boundaries:
            mask = (i3.faces_on_region_boundaries if three_d else itf.edges_on_region_boundaries)(mesh)
        elif c.where is Placement.all:
            mask = (i3.all_faces if three_d else itf.all_edges)(mesh)
        elif (c.where is Placement.surfaces) != three_d:
            raise CaseError(f"{path}: {key} where = '{c.where.value}' is for {'2D' if three_d else '3D'} meshes; "
                            f"this one is {mesh.dim}D: use where = '{'surfaces' if three_d else 'curves'}' with "
                            f"the names of physical {'surfaces' if three_d else 'curves'}")
        else:  # named curves (2D) or surfaces (3D)
            names = given(c.surfaces if three_d else c.curves, f"{key} {c.where.value}")
            groups = mesh.face_sets if three_d else mesh.edge_sets
            require(names, groups, f"{'surface' if three_d else 'curve'} group", f"{key} {c.where.value}", path)
            mask = (i3.faces_on if three_d else itf.edges_on)(mesh, np.vstack([groups[n] for n in names]))
        idx = np.flatnonzero(mask)
        if idx.size == 0:
            raise CaseError(f"{path}: {key}: where = '{c.where.value}' selects no internal {side} of the mesh")
        chosen.append(idx)
        if c.where is Placement.between:  # the first region is the minus side
            minus.append((i3.minus_side if three_d else itf.minus_side)(mesh, idx, regions[0]))
        else:
            minus.append(pair_cells[idx, 0])
    flat = np.concatenate(chosen)
    if np.unique(flat).size != flat.size:
        raise CaseError(f"{path}: [cohesive]: two cohesive sets share {side}s; each {side} can carry one surface")
    n0 = mesh.interfaces.shape[0]
    split = (i3.insert_faces if three_d else itf.insert_interfaces)(mesh, flat, minus_cells=np.concatenate(minus))
    bounds = np.cumsum([0] + [c.size for c in chosen]) + n0
    return split, [np.arange(a, b) for a, b in zip(bounds[:-1], bounds[1:])]
