"""The element groups of a case: one bulk group per material region, one per cohesive set."""

from __future__ import annotations

from typing import Any

import numpy as np

from rockfrac.case.build_mesh import mean_cell_size
from rockfrac.case.messages import require
from rockfrac.case.cohesive_section import CohesiveCommon, CohesiveForm
from rockfrac.case.materials import BulkModel, BulkSection, EmbeddedSection
from rockfrac.case.mesh_section import MeshKind
from rockfrac.case.schema import Case
from rockfrac.elements.cse_corners import CornerEP, CornerRP, corner_points, undetermined_cells
from rockfrac.elements.cse_facets import FacetEP, FacetRP, facet_points
from rockfrac.elements.cse_groups import CohesiveEP, CohesiveRP
from rockfrac.elements.cse_nested import CohesiveRPNested
from rockfrac.elements.ede import EmbeddedDruckerPrager, share_crack_paths
from rockfrac.elements.ede_cracks import cut_along, cut_by_plane
from rockfrac.elements.ede_enrichment import EnrichmentRegistry
from rockfrac.elements.ede_nodal import NodalEmbeddedDruckerPrager
from rockfrac.elements.ede_paths import Exchange
from rockfrac.elements.interface_points import (InterfacePoints, interface_points, interface_points_3d,
                                                 smoothed_normals)
from rockfrac.elements.plastic_solid import DruckerPragerSolid
from rockfrac.elements.solid import ElasticSolid, SolidGroup
from rockfrac.errors import CaseError
from rockfrac.fem.reference import ELEMENTS
from rockfrac.laws.drucker_prager_params import DruckerPrager
from rockfrac.laws.law3d import Law3D
from rockfrac.laws.mohr_coulomb_softening import EmbeddedLaw
from rockfrac.laws.registry import law_class
from rockfrac.laws.traction_law import TractionLaw
from rockfrac.mesh import Mesh
from rockfrac.mesh.interfaces import at_junctions, tied_nodes

AUGMENTATION_SAFETY = 10.0  # r >= this x the law's softening modulus


def stiffest_modulus(case: Case) -> float:
    """The largest Young's modulus of the case's materials [Pa]."""
    return max(m.E for m in case.material_list)


def default_augmentation(case: Case, mesh: Mesh, section) -> float:
    """Augmentation r [Pa/m]: the bulk stiffness seen by the surface, E / h, or ten times the
    law's steepest softening slope if that is larger (the augmented return is then unique).

    The converged solution does not depend on r; it only shapes the iterations.
    """
    law = law_of_section(section)
    return float(max(stiffest_modulus(case) / mean_cell_size(mesh), AUGMENTATION_SAFETY * law.softening_modulus()))


def law_of_section(section) -> TractionLaw:
    """The traction law (plug-in, with its parameters) of a validated [cohesive] or [law] section:
    EP with the section's kn, kt, RP without."""
    return law_class(section.law)(section, kn=section.kn, kt=section.kt)


def drucker_prager_of(bulk) -> DruckerPrager:
    """The Drucker-Prager parameters of a validated (resolved) [bulk] or [[materials]] section."""
    return DruckerPrager(bulk.E, bulk.nu, bulk.beta, bulk.b, bulk.kappa0, bulk.H or 0.0)


def embedded_law(section) -> EmbeddedLaw:
    """The Sect. 4.1 law of a validated [embedded] section (c_p None: eq. 28 per cell)."""
    return EmbeddedLaw(c_r=section.c_r, phi_p=section.phi_p, phi_r=section.phi_r, psi_p=section.psi_p,
                       alpha_c=section.alpha_c, alpha_phi=section.alpha_phi, alpha_psi=section.alpha_psi,
                       c_p=None if section.c_p == "eq28" else float(section.c_p))


def material_cells(case: Case, mesh: Mesh, path: str) -> list[tuple[BulkSection, np.ndarray, str]]:
    """(material section, cell indices, region name) for every material; each cell exactly once."""
    if case.bulk is not None:
        return [(case.bulk, np.arange(mesh.cells.shape[0]), "bulk")]
    materials = case.materials or []
    names = [m.region for m in materials]
    require(names, mesh.regions, "region", "[[materials]] region", path)
    out: list[tuple[BulkSection, np.ndarray, str]] = [(m, np.asarray(mesh.regions[m.region]), m.region)
                                                      for m in materials]
    count = np.zeros(mesh.cells.shape[0], dtype=int)
    for _, cells, _ in out:
        count[cells] += 1
    if np.any(count != 1):
        bad = np.flatnonzero(count != 1)
        raise CaseError(f"{path}: [[materials]]: cells {bad[:5].tolist()} have {count[bad[0]]} materials; the "
                        f"regions {names} must cover every cell once (mesh regions: {sorted(mesh.regions)})")
    return out


def is_embedded(case: Case, section: BulkSection, region: str) -> bool:
    """Whether a material's cells carry embedded cracks: a Drucker-Prager material of [embedded]'s
    regions (every one by default)."""
    emb = case.embedded
    return (emb is not None and section.model is BulkModel.drucker_prager
            and (emb.regions is None or region in emb.regions))


def set_points(section: CohesiveCommon, mesh: Mesh, cells: np.ndarray, root: np.ndarray | None = None) -> InterfacePoints:
    """The integration points of a cohesive set's interface cells ``cells`` (rows of mesh.interfaces):
    nodal, with the set's normals smoothed at the mesh's nodes if it asks for it (``root``:
    :func:`tied_nodes` of the mesh, if made already), or one per cell (points = 'edges', 'faces')."""
    if section.points == "corners":
        return corner_points(mesh.nodes, mesh.interfaces[cells])
    if section.points != "nodes":
        return facet_points(mesh.nodes, mesh.interfaces[cells])[0]
    points = (interface_points if mesh.dim == 2 else interface_points_3d)(mesh.nodes, mesh.interfaces[cells])
    angle = section.smoothing
    if angle is None:
        return points
    root = tied_nodes(mesh) if root is None else root
    return smoothed_normals(points, root[points.minus], angle)


def check_cell_multipliers(section: CohesiveCommon, points: InterfacePoints, name: str, path: str) -> None:
    """RP with one multiplier set per interface cell (points = 'corners', 'edges', 'faces') needs the
    cells' node pairs to determine them (:func:`undetermined_cells`); refused by name otherwise, on the
    whole set, before any step."""
    if section.form is not CohesiveForm.rp or section.points == "nodes" or section.multipliers == "nested":
        return
    loose, n_pairs = undetermined_cells(points.segments)
    if loose:
        raise CaseError(f"{path}: [cohesive] ({name}): form = 'rp' with points = {section.points!r} fixes the mean jump "
                        f"of each interface cell by its own multipliers, but these {points.segments.shape[0]} cells "
                        f"share {n_pairs} node pairs, which leave the multipliers of {loose} of them undetermined (a "
                        "singular saddle point: a surface of triangles has about two faces per node). Take "
                        "points = 'nodes' (a multiplier per node pair), or form = 'ep'")


def cohesive_groups(section, points, mesh: Mesh, name: str, path: str = "<case>", fallback: str = "none",
                    junction: np.ndarray | None = None) -> list:
    """The CSE group of a cohesive set: EP, or RP with augmented multipliers (``junction``: which
    points sit at a junction, found on the whole mesh; None: found on ``mesh``).

    RP at junctions (a node split into k >= 3 copies): the multipliers of the pairs around it are
    statically indeterminate (circulating forces); they are taken with the least circulation from a
    reference traction, see :class:`rockfrac.elements.cse_groups.CohesiveRP`.
    """
    planar = law_of_section(section)
    law: TractionLaw | Law3D = planar
    if mesh.dim == 3:
        key = f"[cohesive] ({name})"
        if section.integration != "implicit" or fallback != "none":
            raise CaseError(f"{path}: {key}: integration = 'implex' and [solver] fallback = 'implex' are 2D only; "
                            "3D surfaces are integrated implicitly (or with [cohesive] viscosity)")
        try:
            law = Law3D(planar)
        except ValueError as err:
            raise CaseError(f"{path}: {key}: {err}") from None
    if section.points == "corners":
        return corner_groups(section, points, mesh, law, name, path, fallback)
    if section.points != "nodes":
        return facet_groups(section, points, mesh, law, name, path, fallback)
    if section.form is CohesiveForm.ep:
        return [CohesiveEP(points, law, name=name, integration=section.integration,
                           viscosity=section.viscosity or 0.0)]
    if section.multipliers == "nested":  # no multiplier unknowns: no junction term (rockfrac.elements.cse_nested)
        return [CohesiveRPNested(points, law, section.augmentation, name=name, viscosity=section.viscosity or 0.0)]
    if junction is None:
        junction = at_junctions(mesh, points.minus)
    return [CohesiveRP(points, law, section.augmentation, junction=junction, name=name,
                       viscosity=section.viscosity or 0.0)]


def facet_groups(section, points: InterfacePoints, mesh: Mesh, law, name: str, path: str, fallback: str) -> list:
    """The CSE group of a set with points = 'edges' or 'faces' (one point per interface cell of ``points``,
    :func:`set_points`, in the order and with the places among the set's of ``points.index``)."""
    key = f"{path}: [cohesive] ({name}): points = {section.points!r}"
    right = "edges" if mesh.dim == 2 else "faces"
    if section.points != right:
        raise CaseError(f"{key}: this mesh is {mesh.dim}D, whose interface cells are {right}: points = {right!r} "
                        "(or 'nodes')")
    if fallback != "none":
        raise CaseError(f"{key} is integrated implicitly: [solver] fallback = {fallback!r} is for nodal points")
    if section.form is CohesiveForm.ep:
        return [FacetEP(points.segments, mesh.nodes, law, name=name, viscosity=section.viscosity or 0.0,
                        index=points.index)]
    return [FacetRP(points.segments, mesh.nodes, law, section.augmentation, name=name,
                    viscosity=section.viscosity or 0.0, index=points.index)]


def corner_groups(section, points: InterfacePoints, mesh: Mesh, law, name: str, path: str, fallback: str) -> list:
    """The CSE group of a set with points = 'corners' (:func:`set_points`: the corners of the set's cells)."""
    if fallback != "none":
        raise CaseError(f"{path}: [cohesive] ({name}): points = 'corners' is integrated implicitly: [solver] "
                        f"fallback = {fallback!r} is for points = 'nodes'")
    if section.form is CohesiveForm.ep:
        return [CornerEP(points, law, name=name, viscosity=section.viscosity or 0.0)]
    return [CornerRP(points, law, section.augmentation, name=name, viscosity=section.viscosity or 0.0)]


def refuse_nodal(case: Case, mesh: Mesh, path: str) -> None:
    """What [embedded] kinematics = 'nodal' does not do, refused by name before any step."""
    if mesh.dim == 3 and case.mesh.kind is MeshKind.specimen:
        raise CaseError(f"{path}: [embedded] kinematics = 'nodal': the plane-strain hexahedra of the paper's "
                        "specimen are not cut (a 2D mesh or a general 3D body)")


def make_bulk_groups(case: Case, mesh: Mesh, path: str = "<case>", owned: np.ndarray | None = None,
                     exchange: Exchange | None = None, rank: int = 0, cell_serial: np.ndarray | None = None,
                     enrichment_nodes: np.ndarray | None = None) -> list:
    """One bulk group per material: elastic, Drucker-Prager, or Drucker-Prager with embedded cracks;
    ``owned`` (a mask over the cells): only these cells (one MPI rank's, ``rank``), ``exchange``: the
    ranks'; on a piece of the mesh, ``cell_serial``: each cell's index among its material's cells in
    the whole mesh, ``enrichment_nodes``: the whole mesh's nodes of the nodal cracks' cells (default:
    the mesh is whole)."""
    ref = ELEMENTS[mesh.cell_type]
    emb = case.embedded
    general = mesh.dim == 3 and case.mesh.kind is not MeshKind.specimen  # not the plane-strain slab
    if emb is not None and general and mesh.cell_type != "hex8" and emb.kinematics != "nodal":
        raise CaseError(f"{path}: [embedded]: embedded cracks in a general 3D body need hex8 cells; these are "
                        f"{mesh.cell_type} (in a tetrahedron whose grad f_S is far from the plane's normal, "
                        "sliding raises the yield function: a cut plane does not converge yet): mesh "
                        "the drucker_prager regions with hexahedra, use kinematics = 'nodal', or remove "
                        "[embedded]")
    if emb is not None and emb.kinematics == "nodal":
        refuse_nodal(case, mesh, path)
    if emb is not None and emb.regions is not None:
        require(emb.regions, mesh.regions, "region", "[embedded] regions", path)
    groups = []
    full: dict[int, tuple] = {}  # an EDE group's cells this rank sees: (whole mesh ids, connectivity)
    whole = mesh.place.cells if mesh.place is not None else np.arange(mesh.cells.shape[0])
    for section, cells, region in material_cells(case, mesh, path):
        every = cells
        serial = cell_serial[every] if cell_serial is not None else np.arange(every.size)
        if owned is not None:
            serial, cells = serial[owned[cells]], cells[owned[cells]]
        sub = mesh.cells[cells]
        dp = section.model is BulkModel.drucker_prager
        if emb is not None and is_embedded(case, section, region):
            kinds: dict[str, Any] = dict(band=emb.band.value, plane_strain=not general, tracking=emb.tracking,
                                         max_cracks=emb.max_cracks, tracking_length=emb.tracking_length,
                                         region=region, cell_ids=cells)
            if emb.kinematics == "nodal":
                assert emb.kn is not None and emb.kt is not None  # the schema requires them
                ede: EmbeddedDruckerPrager = NodalEmbeddedDruckerPrager(
                    mesh.nodes, sub, ref, drucker_prager_of(section), embedded_law(emb), kt=emb.kt, kn=emb.kn,
                    **kinds)
            else:
                ede = EmbeddedDruckerPrager(mesh.nodes, sub, ref, drucker_prager_of(section), embedded_law(emb),
                                            **kinds)
            ede.serial_index = serial  # its cells' places among the whole group's
            full[id(ede)] = (whole[every], mesh.cells[every])
            g: SolidGroup = ede
        elif dp:
            g = DruckerPragerSolid(mesh.nodes, sub, ref, drucker_prager_of(section), region=region, cell_ids=cells)
        else:
            g = ElasticSolid(mesh.nodes, sub, ref, section.E, section.nu, region=region, cell_ids=cells)
        g.whole_ids = whole[cells]
        groups.append(g)

    # one registry for the 2D groups, one for those of a general 3D body (crack paths cross regions)
    embedded = [g for g in groups if isinstance(g, EmbeddedDruckerPrager) and (g.dim == 2 or general)]
    share_crack_paths(embedded, mesh.nodes, [full[id(g)] for g in embedded], exchange)
    for g in groups:  # a plane-strain hex8 group: a registry of its own (its onsets' search over the ranks)
        if isinstance(g, EmbeddedDruckerPrager) and g.dim != 2 and not general:
            share_crack_paths([g], mesh.nodes, [full[id(g)]], exchange)
    nodal = [g for g in groups if isinstance(g, NodalEmbeddedDruckerPrager)]
    if nodal:  # one enrichment for every nodal group (a crack crosses regions), its unknowns owned by the first
        registry = EnrichmentRegistry(nodal, mesh.cells, dim=mesh.dim,
                                      every_cell=[full[id(g)][1] for g in nodal],
                                      exchange=exchange if owned is not None else None, rank=rank,
                                      place=mesh.place, nodes=enrichment_nodes)
        for k, g in enumerate(nodal):
            g.attach(registry, first=k == 0)
    return groups


def cut_given_cracks(case: Case, groups: list, mesh: Mesh, path: str) -> None:
    """Cut the cells of [[embedded.cracks]] (lines in 2D, planes in a general 3D body), once the
    groups hold the state at t = 0 (an in-situ stress: the cracks start from its traction)."""
    emb = case.embedded
    if emb is None or not emb.cracks:
        return
    embedded = [g for g in groups if isinstance(g, EmbeddedDruckerPrager)]
    if mesh.dim == 3 and case.mesh.kind is not MeshKind.specimen:  # a general 3D body (make_bulk_groups)
        cut_initial_planes(emb, embedded, path)
    else:
        cut_initial_cracks(emb, [g for g in embedded if g.dim == 2], path)


def cut_initial_planes(emb: EmbeddedSection, groups: list[EmbeddedDruckerPrager], path: str) -> None:
    """A general 3D body: cut the cells each plane of [[embedded.cracks]] crosses before the first step."""
    if not groups:
        raise CaseError(f"{path}: [embedded] cracks: no cells may localize (cracks need cells of a "
                        "drucker_prager region of [embedded] regions)")
    for k, crack in enumerate(emb.cracks):
        if crack.point is None or crack.normal is None:
            raise CaseError(f"{path}: [embedded] cracks[{k}]: the mesh is a general 3D body; a crack is a plane: "
                            "give point = [x, y, z] and normal = [nx, ny, nz]")
        cut = cut_by_plane(groups, np.array(crack.point, dtype=float), np.array(crack.normal, dtype=float),
                           crack.c_p)
        if cut == 0:
            raise CaseError(f"{path}: [embedded] cracks[{k}]: the plane crosses no cell that may localize (it "
                            "misses the mesh or the drucker_prager regions of [embedded])")


def cut_initial_cracks(emb: EmbeddedSection, groups: list[EmbeddedDruckerPrager], path: str) -> None:
    """Cut the cells of [[embedded.cracks]] before the first step (rockfrac.elements.ede_cracks)."""
    if not groups:
        raise CaseError(f"{path}: [embedded] cracks: no 2D cells may localize (cracks need quad4 or tri3 "
                        "cells of a drucker_prager region of [embedded] regions)")
    for k, crack in enumerate(emb.cracks):
        if crack.points is None:
            raise CaseError(f"{path}: [embedded] cracks[{k}]: a plane (point, normal) cuts a 3D body; this mesh is "
                            "2D: give points = [[x, y], ...]")
        _, covered = cut_along(groups[0].paths, np.array(crack.points, dtype=float), crack.c_p)
        if covered < 1.0 - 1e-6:
            raise CaseError(f"{path}: [embedded] cracks[{k}]: {100 * (1 - covered):.3g} % of its length is not "
                            "across cells that may localize (it leaves the mesh or the drucker_prager regions "
                            "of [embedded])")


