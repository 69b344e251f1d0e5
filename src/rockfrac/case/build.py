"""Turn a validated Case into a Model, its load stages and the quantities to report.

Every input problem (a region or boundary group the mesh does not have, an inverted cell...)
surfaces here as a CaseError, before any step is taken.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from rockfrac.case.schema import BulkModel, Case, CaseError, CohesiveForm, Control, ElementType, MeshKind, Placement
from rockfrac.elements.cse_groups import CohesiveEP, CohesiveRP
from rockfrac.elements.ede import EmbeddedDruckerPrager
from rockfrac.elements.interface_points import interface_points
from rockfrac.elements.plastic_solid import DruckerPragerSolid
from rockfrac.elements.solid import ElasticSolid, SolidGroup
from rockfrac.fem.conditions import edge_pressure, face_pressure
from rockfrac.fem.reference import ELEMENTS
from rockfrac.laws.cohesive_params import CohesiveLaw
from rockfrac.laws.drucker_prager_params import DruckerPrager
from rockfrac.laws.mohr_coulomb_softening import EmbeddedLaw
from rockfrac.mesh import Mesh, cracked_specimen, hex_specimen
from rockfrac.model import Model
from rockfrac.solve.stepping import PathSpec, Stage


@dataclass
class Built:
    """Everything a run needs: the model, its stages and where to read the axial response."""

    case: Case
    mesh: Mesh
    model: Model
    stages: list[Stage]
    top_y_dofs: np.ndarray  # prescribed axial dofs (reaction -> F_axial)
    thickness: float  # forces are reported per unit thickness: 1 in 2D, T for hex8 [m]
    bulks: list = field(default_factory=list)  # one group per material region
    cohesives: list = field(default_factory=list)  # one CSE group per cohesive set

    @property
    def bulk(self):
        """The bulk group (the first one with several materials)."""
        return self.bulks[0]

    @property
    def cohesive(self) -> CohesiveEP | CohesiveRP | None:
        """The cohesive group (the first one with several sets), or None."""
        return self.cohesives[0] if self.cohesives else None

    @property
    def embeddeds(self) -> list[EmbeddedDruckerPrager]:
        return [g for g in self.bulks if isinstance(g, EmbeddedDruckerPrager)]

    @property
    def embedded(self) -> EmbeddedDruckerPrager | None:
        """The bulk group that carries embedded discontinuities (the first one), or None."""
        e = self.embeddeds
        return e[0] if e else None


AUGMENTATION_SAFETY = 10.0  # r >= this x the law's softening modulus


def stiffest_modulus(case: Case) -> float:
    """The largest Young's modulus of the case's materials [Pa]."""
    return max(m.E for m in case.material_list)


def mean_cell_size(mesh: Mesh) -> float:
    """sqrt of the mean cell area (2D) [m]."""
    x = mesh.nodes[mesh.cells][..., :2]
    area = 0.5 * np.abs(np.sum(x[:, :, 0] * np.roll(x[:, :, 1], -1, 1) - np.roll(x[:, :, 0], -1, 1) * x[:, :, 1], 1))
    return float(np.sqrt(area.mean()))


def default_augmentation(case: Case, mesh: Mesh, section) -> float:
    """Augmentation r [Pa/m]: the bulk stiffness seen by the surface, E / h, or ten times the
    law's steepest softening slope if that is larger (the augmented return is then unique).

    The converged solution does not depend on r; it only shapes the iterations.
    """
    law = law_of_section(section)
    return float(max(stiffest_modulus(case) / mean_cell_size(mesh), AUGMENTATION_SAFETY * law.softening_modulus()))


def resolve(case: Case, path: str = "<case>") -> Case:
    """Fill every default, including those that depend on the case (path control, RP augmentation)."""
    case = case.resolved()
    load = case.loading
    if load.control is Control.path:
        nominal = abs(load.axial_targets[0]) / load.axial_steps
        load = load.model_copy(update={"path_increment": load.path_increment or nominal,
                                       "max_steps": load.max_steps or 20 * load.axial_steps})
        case = case.model_copy(update={"loading": load})
    if not any(c.form is CohesiveForm.rp and c.augmentation is None for c in case.cohesive_sets):
        return case
    mesh = make_mesh(case, path)
    sets = [c.model_copy(update={"augmentation": c.augmentation or default_augmentation(case, mesh, c)})
            if c.form is CohesiveForm.rp else c for c in case.cohesive_sets]
    return case.model_copy(update={"cohesive": sets})


def make_mesh(case: Case, path: str = "<case>") -> Mesh:
    """The bulk mesh of the case (before any cohesive insertion), checked."""
    m = case.mesh.resolved()
    try:
        if m.kind is MeshKind.gmsh:
            from rockfrac.mesh.gmsh_io import read_mesh

            try:
                mesh = read_mesh(m.file, dim=None)
            except CaseError as err:
                raise CaseError(f"{path}: [mesh] file: {err}") from None
        elif m.kind is MeshKind.grains:
            from rockfrac.mesh.grains import grain_specimen

            mesh = grain_specimen(m.width, m.height, n_grains=m.n_grains, radius=(m.radius_min, m.radius_max),
                                  seed=m.seed, element_size=m.element_size, element=m.element.value)
        elif m.kind is MeshKind.block:
            from rockfrac.mesh.grains import block_with_inclusion

            mesh = block_with_inclusion(m.width, m.height, m.nx, m.ny, inclusion=m.inclusion,
                                        element=m.element.value)
        elif m.element is ElementType.hex8:
            mesh = hex_specimen(m.width, m.height, m.thickness, m.nx, m.ny, m.nz)
        else:
            try:
                mesh = cracked_specimen(m.width, m.height, m.crack_angle or 0.0, m.nx, m.ny, crack=m.crack)
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


def law_of_section(section) -> CohesiveLaw:
    """The law's parameter object from a validated [cohesive] or [law] section."""
    names = CohesiveLaw.__dataclass_fields__
    return CohesiveLaw(**{k: getattr(section, k) for k in names if getattr(section, k, None) is not None})


def drucker_prager_of(bulk) -> DruckerPrager:
    """The Drucker-Prager parameters of a validated (resolved) [bulk] or [[materials]] section."""
    return DruckerPrager(bulk.E, bulk.nu, bulk.beta, bulk.b, bulk.kappa0, bulk.H or 0.0)


def embedded_law(section) -> EmbeddedLaw:
    """The Sect. 4.1 law of a validated [embedded] section (c_p None: eq. 28 per cell)."""
    return EmbeddedLaw(c_r=section.c_r, phi_p=section.phi_p, phi_r=section.phi_r, psi_p=section.psi_p,
                       alpha_c=section.alpha_c, alpha_phi=section.alpha_phi, alpha_psi=section.alpha_psi,
                       c_p=None if section.c_p == "eq28" else float(section.c_p))


def _require(names, available, what: str, key: str, path: str) -> None:
    missing = [n for n in names if n not in available]
    if missing:
        raise CaseError(f"{path}: {key}: {what} {', '.join(repr(n) for n in missing)} not in the mesh; "
                        f"its {what}s: {', '.join(sorted(available)) or '(none)'}")


def _material_cells(case: Case, mesh: Mesh, path: str) -> list[tuple[object, np.ndarray, str]]:
    """(material section, cell indices, region name) for every material; each cell exactly once."""
    if case.bulk is not None:
        return [(case.bulk, np.arange(mesh.cells.shape[0]), "bulk")]
    names = [m.region for m in case.materials]
    _require(names, mesh.regions, "region", "[[materials]] region", path)
    out = [(m, np.asarray(mesh.regions[m.region]), m.region) for m in case.materials]
    count = np.zeros(mesh.cells.shape[0], dtype=int)
    for _, cells, _ in out:
        count[cells] += 1
    if np.any(count != 1):
        bad = np.flatnonzero(count != 1)
        raise CaseError(f"{path}: [[materials]]: cells {bad[:5].tolist()} have {count[bad[0]]} materials; the "
                        f"regions {names} must cover every cell once (mesh regions: {sorted(mesh.regions)})")
    return out


def _insert_cohesive(case: Case, mesh: Mesh, path: str) -> tuple[Mesh, list[np.ndarray]]:
    """Split the mesh along every cohesive set's edges; returns the new mesh and each set's cells."""
    sets = case.cohesive_sets
    if not sets:
        return mesh, []
    if sets[0].where is Placement.crack:  # the specimen carries its crack already
        return mesh, [np.arange(mesh.interfaces.shape[0])]
    from rockfrac.mesh import interfaces as itf

    edges, cells, _ = itf.internal_edges(mesh)
    chosen, minus = [], []
    for k, c in enumerate(sets):
        key = f"[cohesive{'' if len(sets) == 1 else f' {k + 1}'}]"
        if c.where in (Placement.between, Placement.within):
            _require(c.regions, mesh.regions, "region", f"{key} regions", path)
        if c.where is Placement.between:
            mask = itf.edges_between(mesh, *c.regions)
        elif c.where is Placement.within:
            mask = itf.edges_within(mesh, c.regions[0])
        elif c.where is Placement.curves:
            _require(c.curves, mesh.edge_sets, "curve group", f"{key} curves", path)
            mask = itf.edges_on(mesh, np.vstack([mesh.edge_sets[n] for n in c.curves]))
        else:
            mask = itf.all_edges(mesh)
        idx = np.flatnonzero(mask)
        if idx.size == 0:
            raise CaseError(f"{path}: {key}: where = '{c.where.value}' selects no internal edge of the mesh")
        chosen.append(idx)
        if c.where is Placement.between:  # the first region is the minus side
            minus.append(itf.minus_side(mesh, idx, c.regions[0]))
        else:
            minus.append(cells[idx, 0])
    flat = np.concatenate(chosen)
    if np.unique(flat).size != flat.size:
        raise CaseError(f"{path}: [cohesive]: two cohesive sets share edges; each edge can carry one surface")
    n0 = mesh.interfaces.shape[0]
    split = itf.insert_interfaces(mesh, flat, minus_cells=np.concatenate(minus))
    bounds = np.cumsum([0] + [c.size for c in chosen]) + n0
    return split, [np.arange(a, b) for a, b in zip(bounds[:-1], bounds[1:])]


def cohesive_groups(section, points, mesh: Mesh, name: str) -> list:
    """The CSE group of a cohesive set: EP, or RP with augmented multipliers.

    RP at junctions (a node split into k >= 3 copies): the multipliers of the pairs around it are
    statically indeterminate (circulating forces); they are taken with the least circulation, see
    :class:`rockfrac.elements.cse_groups.CohesiveRP`.
    """
    law = law_of_section(section)
    if section.form is CohesiveForm.ep:
        return [CohesiveEP(points, law, name=name)]
    from rockfrac.mesh.interfaces import tied_nodes

    root = tied_nodes(mesh)
    copies = np.bincount(root, minlength=mesh.n_nodes)
    return [CohesiveRP(points, law, section.augmentation, junction=copies[root[points.minus]] >= 3, name=name)]


def make_bulk_groups(case: Case, mesh: Mesh, path: str = "<case>") -> list:
    """One bulk group per material: elastic, Drucker-Prager, or Drucker-Prager with embedded cracks."""
    ref = ELEMENTS[mesh.cell_type]
    emb = case.embedded
    ede_regions = None
    if emb is not None and emb.regions is not None:
        _require(emb.regions, mesh.regions, "region", "[embedded] regions", path)
        ede_regions = set(emb.regions)
    groups = []
    for section, cells, region in _material_cells(case, mesh, path):
        sub = mesh.cells[cells]
        dp = section.model is BulkModel.drucker_prager
        if emb is not None and dp and (ede_regions is None or region in ede_regions):
            g: SolidGroup = EmbeddedDruckerPrager(
                mesh.nodes, sub, ref, drucker_prager_of(section), embedded_law(emb), band=emb.band.value,
                plane_strain=True, tracking=emb.tracking, max_cracks=emb.max_cracks, region=region, cell_ids=cells)
        elif dp:
            g = DruckerPragerSolid(mesh.nodes, sub, ref, drucker_prager_of(section), region=region, cell_ids=cells)
        else:
            g = ElasticSolid(mesh.nodes, sub, ref, section.E, section.nu, region=region, cell_ids=cells)
        groups.append(g)
    from rockfrac.elements.ede import share_crack_paths

    share_crack_paths([g for g in groups if isinstance(g, EmbeddedDruckerPrager) and g.dim == 2], mesh.nodes)
    return groups


def build(case: Case, path: str = "<case>") -> Built:
    """The model: mesh (split where cohesive surfaces go), bulk and surface groups, conditions."""
    case = resolve(case, path)
    mesh, set_cells = _insert_cohesive(case, make_mesh(case, path), path)
    dim = mesh.dim
    try:
        bulks = make_bulk_groups(case, mesh, path)
    except ValueError as err:
        raise CaseError(f"{path}: [mesh]: {err}") from None
    cohesives = []
    for k, (section, cells) in enumerate(zip(case.cohesive_sets, set_cells)):
        cohesives += cohesive_groups(section, interface_points(mesh.nodes, mesh.interfaces[cells]), mesh,
                                     f"cohesive {k + 1}")
    load = case.loading
    for key in ("support", "pin", "axial"):
        _require([getattr(load, key)], mesh.node_sets, "node group", f"[loading] {key}", path)
    sets = mesh.node_sets
    top_y = dim * sets[load.axial] + 1
    held = [dim * sets[load.support] + 1, dim * sets[load.pin], top_y]
    if dim == 3:  # plane strain: both out-of-plane faces held in their normal direction
        _require(["back", "front"], sets, "node group", "[mesh] (3D plane strain needs the out-of-plane faces)",
                 path)
        held += [3 * sets["back"] + 2, 3 * sets["front"] + 2]
    dirichlet = np.unique(np.concatenate(held))
    model = Model(mesh.n_nodes, bulks + cohesives, dirichlet, dim=dim)
    surfaces = cohesives or [g for g in bulks if isinstance(g, EmbeddedDruckerPrager)]
    stages = _stages(case, mesh, model, top_y, surfaces, path)
    thickness = case.mesh.resolved().thickness if dim == 3 else 1.0
    return Built(case, mesh, model, stages, top_y, thickness, bulks, cohesives)


def _stages(case: Case, mesh: Mesh, model: Model, top_y: np.ndarray, surfaces: list, path: str) -> list[Stage]:
    load = case.loading
    f_conf = np.zeros(model.n_dofs)
    groups = mesh.edge_sets if mesh.dim == 2 else mesh.face_sets
    _require(load.pressure, groups, "boundary group", "[loading] pressure", path)
    if mesh.dim == 2:
        from rockfrac.mesh.gmsh_io import on_boundary

        inside = [side for side in load.pressure if not on_boundary(mesh, groups[side]).all()]
        if inside:
            raise CaseError(f"{path}: [loading] pressure: {', '.join(repr(s) for s in inside)} are not (all) on "
                            "the boundary; the confining pressure acts on boundary edges")
    for side in load.pressure:
        if mesh.dim == 2:
            edge_pressure(mesh.nodes, groups[side], load.confinement, f_conf)
        else:
            face_pressure(mesh.nodes, groups[side], load.confinement, f_conf)
    n_d = model.dirichlet.shape[0]
    on_top = np.isin(model.dirichlet, top_y)
    stages = [Stage("confinement", load.confinement_steps, np.zeros(n_d), f_conf,
                    source=f"{path}: [loading] confinement = {load.confinement:g} Pa")]
    for k, target in enumerate(load.axial_targets):
        d_axial = np.where(on_top, -target, 0.0)
        name = "axial" if k == 0 else f"axial {k + 1}"
        key = "axial_displacement" if len(load.axial_targets) == 1 else f"axial_displacement[{k + 1}]"
        stages.append(Stage(name, load.axial_steps, d_axial, f_conf, _path(load, surfaces, path, model.n_dofs),
                            source=f"{path}: [loading] {key} = {target:g} m"))
    return stages


class _CombinedPath:
    """Path measure over several surface groups: their measures averaged by number of points."""

    def __init__(self, surfaces: list, n_dofs: int):
        self.surfaces = surfaces
        self.n_dofs = n_dofs

    def weights(self) -> np.ndarray:
        n = np.array([g.path_weight() for g in self.surfaces], dtype=float)
        return n / n.sum()

    def measure(self):
        parts = [g.path_measure(self.n_dofs) for g in self.surfaces]
        w = self.weights()

        def combined(u: np.ndarray) -> tuple[float, np.ndarray]:
            values, grads = zip(*(m(u) for m in parts))
            return float(np.dot(w, values)), sum(wi * gi for wi, gi in zip(w, grads))

        return combined

    def active(self) -> bool:
        return any(g.path_active() for g in self.surfaces)


def _path(load, surfaces: list, path: str, n_dofs: int) -> PathSpec | None:
    """Path following on the discontinuities' jumps: CSE node pairs, or embedded cells."""
    if load.control is not Control.path:
        return None
    if not surfaces:  # the schema allows path control only with cohesive surfaces or [embedded]
        raise CaseError(f"{path}: [loading] control = 'path' needs a cohesive surface or an [embedded] section")
    combined = _CombinedPath(surfaces, n_dofs)
    measure = (lambda: surfaces[0].path_measure(n_dofs)) if len(surfaces) == 1 else combined.measure
    return PathSpec(measure, load.path_increment, combined.active, load.max_steps)
