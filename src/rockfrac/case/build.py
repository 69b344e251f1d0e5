"""Turn a validated Case into a Model, its load stages and the quantities to report."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rockfrac.case.schema import BulkModel, Case, CaseError, CohesiveForm, Control, ElementType
from rockfrac.elements.cse_groups import CohesiveEP, CohesiveRP
from rockfrac.elements.ede import EmbeddedDruckerPrager
from rockfrac.elements.interface_points import interface_points
from rockfrac.elements.plastic_solid import DruckerPragerSolid
from rockfrac.elements.solid import ElasticSolid
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
    bulk: ElasticSolid | DruckerPragerSolid | EmbeddedDruckerPrager
    cohesive: CohesiveEP | CohesiveRP | None

    @property
    def embedded(self) -> EmbeddedDruckerPrager | None:
        """The bulk group when it carries embedded discontinuities."""
        return self.bulk if isinstance(self.bulk, EmbeddedDruckerPrager) else None


AUGMENTATION_SAFETY = 10.0  # r >= this x the law's softening modulus


def default_augmentation(case: Case, mesh: Mesh) -> float:
    """Augmentation r [Pa/m]: the bulk stiffness seen by the surface, E / h, or ten times the
    law's steepest softening slope if that is larger (the augmented return is then unique).

    The converged solution does not depend on r; it only shapes the iterations.
    """
    x = mesh.nodes[mesh.cells]
    area = 0.5 * np.abs(
        np.sum(x[:, :, 0] * np.roll(x[:, :, 1], -1, 1) - np.roll(x[:, :, 0], -1, 1) * x[:, :, 1], 1)
    )
    law = law_of_section(case.cohesive)
    return float(max(case.bulk.E / np.sqrt(area.mean()), AUGMENTATION_SAFETY * law.softening_modulus()))


def resolve(case: Case) -> Case:
    """Fill every default, including those that depend on the case (path control, RP augmentation)."""
    case = case.resolved()
    load = case.loading
    if load.control is Control.path:
        nominal = abs(load.axial_targets[0]) / load.axial_steps
        load = load.model_copy(update={"path_increment": load.path_increment or nominal,
                                       "max_steps": load.max_steps or 20 * load.axial_steps})
        case = case.model_copy(update={"loading": load})
    coh = case.cohesive
    if coh is None or coh.form is not CohesiveForm.rp:
        return case
    mesh = make_mesh(case)
    r = coh.augmentation or default_augmentation(case, mesh)
    coh = coh.model_copy(update={"augmentation": r})
    return case.model_copy(update={"cohesive": coh})


def make_mesh(case: Case, path: str = "<case>") -> Mesh:
    m = case.mesh.resolved()
    try:
        if m.element is ElementType.hex8:
            mesh = hex_specimen(m.width, m.height, m.thickness, m.nx, m.ny, m.nz)
        else:
            mesh = cracked_specimen(m.width, m.height, m.crack_angle or 0.0, m.nx, m.ny, crack=m.crack)
    except ValueError as err:
        raise CaseError(f"{path}: [mesh] crack_angle: {err}") from None
    problems = mesh.check()
    if problems:
        raise CaseError(f"{path}: [mesh]: " + "; ".join(problems))
    return mesh


def law_of_section(section) -> CohesiveLaw:
    """The law's parameter object from a validated [cohesive] or [law] section."""
    names = CohesiveLaw.__dataclass_fields__
    return CohesiveLaw(**{k: getattr(section, k) for k in names if getattr(section, k, None) is not None})


def drucker_prager_of(bulk) -> DruckerPrager:
    """The Drucker-Prager parameters of a validated (resolved) [bulk] section."""
    return DruckerPrager(bulk.E, bulk.nu, bulk.beta, bulk.b, bulk.kappa0, bulk.H or 0.0)


def embedded_law(section) -> EmbeddedLaw:
    """The Sect. 4.1 law of a validated [embedded] section (c_p None: eq. 28 per cell)."""
    return EmbeddedLaw(c_r=section.c_r, phi_p=section.phi_p, phi_r=section.phi_r, psi_p=section.psi_p,
                       alpha_c=section.alpha_c, alpha_phi=section.alpha_phi, alpha_psi=section.alpha_psi,
                       c_p=None if section.c_p == "eq28" else float(section.c_p))


def make_bulk(case: Case, mesh: Mesh):
    """The bulk element group of the case's material."""
    ref = ELEMENTS[mesh.cell_type]
    if case.embedded is not None:  # plane strain: the specimen's hex is held on both faces
        return EmbeddedDruckerPrager(mesh.nodes, mesh.cells, ref, drucker_prager_of(case.bulk),
                                     embedded_law(case.embedded), band=case.embedded.band.value,
                                     plane_strain=True)
    if case.bulk.model is BulkModel.drucker_prager:
        return DruckerPragerSolid(mesh.nodes, mesh.cells, ref, drucker_prager_of(case.bulk))
    return ElasticSolid(mesh.nodes, mesh.cells, ref, case.bulk.E, case.bulk.nu)


def build(case: Case, path: str = "<case>") -> Built:
    """Model of the specimen: bulk, the crack's CSE group, BCs of PAPER_NOTES Sect. 7."""
    case = resolve(case)
    mesh = make_mesh(case, path)
    dim = mesh.dim
    bulk = make_bulk(case, mesh)
    groups: list = [bulk]
    cohesive = None
    if case.cohesive is not None:
        points = interface_points(mesh.nodes, mesh.interfaces)
        law = law_of_section(case.cohesive)
        if case.cohesive.form is CohesiveForm.ep:
            cohesive = CohesiveEP(points, law)
        else:
            cohesive = CohesiveRP(points, law, case.cohesive.augmentation)
        groups.append(cohesive)
    sets = mesh.node_sets
    top_y = dim * sets["top"] + 1
    held = [dim * sets["bottom"] + 1, dim * sets["bottom_left"], top_y]
    if dim == 3:  # plane strain: both out-of-plane faces held in their normal direction
        held += [3 * sets["back"] + 2, 3 * sets["front"] + 2]
    dirichlet = np.unique(np.concatenate(held))
    model = Model(mesh.n_nodes, groups, dirichlet, dim=dim)
    stages = _stages(case, mesh, model, top_y, cohesive if cohesive is not None else
                     (bulk if isinstance(bulk, EmbeddedDruckerPrager) else None))
    thickness = case.mesh.resolved().thickness if dim == 3 else 1.0
    return Built(case, mesh, model, stages, top_y, thickness, bulk, cohesive)


def _stages(case: Case, mesh: Mesh, model: Model, top_y: np.ndarray, cohesive) -> list[Stage]:
    load = case.loading
    f_conf = np.zeros(model.n_dofs)
    for side in ("left", "right"):
        if mesh.dim == 2:
            edge_pressure(mesh.nodes, mesh.edge_sets[side], load.confinement, f_conf)
        else:
            face_pressure(mesh.nodes, mesh.face_sets[side], load.confinement, f_conf)
    n_d = model.dirichlet.shape[0]
    on_top = np.isin(model.dirichlet, top_y)
    stages = [Stage("confinement", load.confinement_steps, np.zeros(n_d), f_conf)]
    for k, target in enumerate(load.axial_targets):
        d_axial = np.where(on_top, -target, 0.0)
        name = "axial" if k == 0 else f"axial {k + 1}"
        stages.append(Stage(name, load.axial_steps, d_axial, f_conf, _path(load, cohesive)))
    return stages


def _path(load, surface) -> PathSpec | None:
    """Path following on the discontinuity's jump: CSE node pairs, or the embedded cells' zeta."""
    if load.control is not Control.path:
        return None
    if surface is None:  # the schema allows path control only with a crack or [embedded]
        raise CaseError("[loading] control = 'path' needs a cohesive crack or an [embedded] section")
    active = surface.any_sliding if isinstance(surface, EmbeddedDruckerPrager) else surface.any_plastic
    return PathSpec(surface.jump_measure, load.path_increment, active, load.max_steps)
