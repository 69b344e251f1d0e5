"""The state at t = 0: the in-situ stress of [initial] (a linear field per set of regions), the
groups it is put into, the nodal forces of its tractions on the boundary (and the traction per
side a nodal crack's enrichment shares), and gravity's nodal forces."""

from __future__ import annotations

import numpy as np

from rockfrac.case.messages import require
from rockfrac.case.program import InitialStressSection
from rockfrac.errors import CaseError
from rockfrac.fem.loads import (
    StressField,
    body_force,
    edge_stress_traction,
    face_stress_traction,
    nodal_volumes,
    side_normals,
)
from rockfrac.mesh.mesh import Mesh
from rockfrac.mesh.topology import side_cells
from rockfrac.model import Model


class InitialStress:
    """The in-situ stress of the case: one linear field per set of regions (sigma0 = stress + (e -
    datum) gradient, e the elevation: y in 2D, z in 3D)."""

    def __init__(self, specs: list[InitialStressSection], regions: list[str], dim: int, path: str):
        self.dim = dim
        self.of_region: dict[str, tuple[np.ndarray, np.ndarray, float]] = {}
        for k, spec in enumerate(specs):
            key = f"[initial] stress[{k + 1}]"
            names = spec.regions if spec.regions is not None else regions
            require(names, regions, "region", f"{key} regions", path)
            s = np.zeros(6)
            g = np.zeros(6)
            n = len(spec.stress)
            if dim == 3 and n != 6:
                raise CaseError(f"{path}: {key} stress: a 3D mesh needs all six components (sxx, syy, szz, sxy, syz, sxz)")
            s[[0, 1, 2, 3, 4, 5][:n]] = spec.stress
            if spec.gradient is not None:
                g[:n] = spec.gradient
            for r in names:
                if r in self.of_region:
                    raise CaseError(f"{path}: {key} regions: region {r!r} already has an in-situ stress")
                self.of_region[r] = (s, g, spec.datum)

    def field(self, region: str) -> StressField | None:
        """The stress field of a region (None: stress-free)."""
        if region not in self.of_region:
            return None
        s, g, datum = self.of_region[region]
        axis = 1 if self.dim == 2 else 2

        def stress(x: np.ndarray) -> np.ndarray:
            return s[None, :] + (x[:, axis] - datum)[:, None] * g[None, :]

        return stress

    def scale(self) -> float:
        """The largest stress magnitude at the datum [Pa] (for tolerances)."""
        return max((float(np.abs(s).max()) for s, _, _ in self.of_region.values()), default=0.0)


def _cell_regions(n_cells: int, bulks: list) -> np.ndarray:
    out = np.full(n_cells, -1)
    for k, g in enumerate(bulks):
        out[g.cell_ids] = k
    return out


def own_sides(mesh: Mesh, bulks: list, sides: np.ndarray) -> np.ndarray:
    """The boundary sides whose cell is one of the groups' (an MPI rank's own: each side on one rank)."""
    return sides[_side_regions(mesh, bulks, sides) >= 0]


def _side_regions(mesh: Mesh, bulks: list, sides: np.ndarray) -> np.ndarray:
    """The group (index into ``bulks``) of each side's cell, -1 where none of the groups has it."""
    cells = side_cells(mesh, sides)
    return np.where(cells >= 0, _cell_regions(mesh.cells.shape[0], bulks)[cells], -1)


def in_situ_forces(mesh: Mesh, bulks: list, initial: InitialStress, sides: np.ndarray,
                   factor: np.ndarray) -> np.ndarray:
    """Nodal forces of sigma0 . n on boundary sides (each side with the field of its cell's region),
    times a factor per side, over the global displacement dofs: the sides of the groups' cells only
    (an MPI rank's share; :meth:`rockfrac.model.Model.summed` adds the ranks')."""
    f = np.zeros(mesh.dim * mesh.n_nodes)
    if sides.size == 0:
        return f
    region_of = _side_regions(mesh, bulks, sides)
    for k, g in enumerate(bulks):
        field_ = initial.field(g.region)
        on = region_of == k
        if field_ is None or not on.any():
            continue
        if mesh.dim == 2:
            edge_stress_traction(mesh.nodes, sides[on], field_, f, factor[on])
        else:
            face_stress_traction(mesh.nodes, sides[on], field_, f, factor[on])
    return f


def in_situ_tractions(mesh: Mesh, bulks: list, initial: InitialStress, sides: np.ndarray,
                      factor: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The loaded boundary sides of :func:`in_situ_forces` and the traction sigma0 . n [Pa] at each of
    their nodes (m, s, dim), times the side's factor: the share a nodal crack crossing a side takes
    (rockfrac.elements.ede_enrichment.EnrichmentRegistry.surface_forces, interpolated along the side:
    exact for the linear fields of [initial])."""
    dim = mesh.dim
    on = np.asarray(factor) != 0.0
    sides, factor = sides[on], np.asarray(factor)[on]
    t = np.zeros((sides.shape[0], sides.shape[1], dim))
    region_of = _side_regions(mesh, bulks, sides)
    normal = side_normals(mesh.nodes, sides)
    pairs = [(0, 3), (3, 1)] if dim == 2 else [(0, 3, 5), (3, 1, 4), (5, 4, 2)]  # Voigt rows of sigma
    for k, g in enumerate(bulks):
        field_ = initial.field(g.region)
        rows = region_of == k
        if field_ is None or not rows.any():
            continue
        x = mesh.nodes[sides[rows]]  # (r, s, 3)
        sig = field_(x.reshape(-1, x.shape[-1])[:, :dim]).reshape(x.shape[0], x.shape[1], 6)
        for i, voigt in enumerate(pairs):
            t[rows, :, i] = sum(sig[..., v] * normal[rows, None, j] for j, v in enumerate(voigt))
    return sides, t * factor[:, None, None]


def set_initial_stress(mesh: Mesh, bulks: list, cohesives: list, initial: InitialStress, model: Model,
                       minus_groups: list[np.ndarray] | None = None) -> None:
    """Put the in-situ stress into the groups: bulk regions their own field, cohesive sets the field
    of the region on their minus side (the last bulk group whose cells hold their minus nodes, found
    here, or given for each set's points: ``minus_groups``, an MPI rank's, found on the whole mesh;
    over the points of every rank)."""
    node_group = np.full(mesh.n_nodes, -1)
    for k, g in enumerate(bulks):
        field_ = initial.field(g.region)
        if field_ is not None:
            g.set_initial_stress(field_)
        node_group[g.cells.ravel()] = k
    for j, c in enumerate(cohesives):
        mine = minus_groups[j] if minus_groups is not None else node_group[c.points.minus]
        groups = set().union(*model.allgather(set(mine.tolist())))
        fields = {bulks[k].region: initial.field(bulks[k].region) for k in groups if k >= 0}
        specs = {initial.of_region[r][0].tobytes() + initial.of_region[r][1].tobytes()
                 for r, fl in fields.items() if fl is not None}
        if len(specs) > 1:
            raise CaseError(f"[initial] stress: the cohesive set {c.name!r} borders regions with different in-situ "
                            f"stresses ({', '.join(sorted(fields))}); give them one field")
        live = [fl for fl in fields.values() if fl is not None]
        if live:
            c.set_initial_stress(live[0])


def gravity_forces(bulks: list, densities: dict[str, float | None], mesh: Mesh, g: np.ndarray, key: str,
                   path: str) -> np.ndarray:
    """Nodal forces of gravity g on every region (density x g) over the global displacement dofs, CaseError
    if a region has no density: the groups' cells only (an MPI rank's share; :meth:`rockfrac.model.Model.summed`
    adds the ranks')."""
    f = np.zeros(mesh.dim * mesh.n_nodes)
    if not np.any(g):
        return f
    for b in bulks:
        rho = densities.get(b.region)
        if rho is None:
            raise CaseError(f"{path}: {key}: region {b.region!r} has no density (give density [kg/m^3] in its "
                            "[bulk] or [[materials]] section)")
        body_force(b.cells, nodal_volumes(mesh.nodes, b.cells, b.ref, b.wdet), rho, g, f)
    return f
