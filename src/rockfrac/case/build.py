"""Turn a validated Case into a Model, its load stages and the quantities to report."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rockfrac.case.schema import Case, CaseError, CohesiveForm, Control
from rockfrac.elements.cse_groups import CohesiveEP, CohesiveRP
from rockfrac.elements.solid import ElasticSolid
from rockfrac.fem.reference import ELEMENTS
from rockfrac.elements.interface_points import interface_points
from rockfrac.fem.conditions import edge_pressure
from rockfrac.laws.cohesive_params import CohesiveLaw
from rockfrac.mesh import Mesh, cracked_specimen
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
    bulk: ElasticSolid
    cohesive: CohesiveEP | CohesiveRP | None


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
    """Fill the defaults that depend on the case (path-control sizes, RP augmentation)."""
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
    m = case.mesh
    try:
        mesh = cracked_specimen(m.width, m.height, m.crack_angle, m.nx, m.ny, crack=m.crack)
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


def build(case: Case, path: str = "<case>") -> Built:
    """Model of the specimen: bulk Q4s, the crack's CSE group, BCs of PAPER_NOTES Sect. 7."""
    case = resolve(case)
    mesh = make_mesh(case, path)
    bulk = ElasticSolid(mesh.nodes, mesh.cells, ELEMENTS[mesh.cell_type], case.bulk.E, case.bulk.nu)
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
    bottom, top = mesh.node_sets["bottom"], mesh.node_sets["top"]
    corner = mesh.node_sets["bottom_left"]
    top_y = 2 * top + 1
    dirichlet = np.concatenate([2 * bottom + 1, 2 * corner, top_y])
    model = Model(mesh.n_nodes, groups, dirichlet)
    stages = _stages(case, mesh, model, top_y, cohesive)
    return Built(case, mesh, model, stages, top_y, bulk, cohesive)


def _stages(case: Case, mesh: Mesh, model: Model, top_y: np.ndarray, cohesive) -> list[Stage]:
    load = case.loading
    f_conf = np.zeros(model.n_dofs)
    for side in ("left", "right"):
        edge_pressure(mesh.nodes, mesh.edge_sets[side], load.confinement, f_conf)
    n_d = model.dirichlet.shape[0]
    on_top = np.isin(model.dirichlet, top_y)
    stages = [Stage("confinement", load.confinement_steps, np.zeros(n_d), f_conf)]
    for k, target in enumerate(load.axial_targets):
        d_axial = np.where(on_top, -target, 0.0)
        name = "axial" if k == 0 else f"axial {k + 1}"
        stages.append(Stage(name, load.axial_steps, d_axial, f_conf, _path(load, cohesive)))
    return stages


def _path(load, cohesive) -> PathSpec | None:
    if load.control is not Control.path:
        return None
    return PathSpec(cohesive.jump_measure, load.path_increment, cohesive.any_plastic, load.max_steps)
