"""The loading program of a case as engine stages: prescribed dofs and forces per stage, the state
at t = 0 (in-situ stress, gravity) and the stop rules.

Every group a stage names is checked against the mesh here, before any step, with the stage and
key in the message. The paper's short form [loading] is expanded into two or more stages first
(:func:`expand_loading`), so both forms run through the same code.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from rockfrac.case.loading import Control
from rockfrac.case.initial_state import (
    InitialStress,
    gravity_forces,
    in_situ_forces,
    in_situ_tractions,
    own_sides,
    set_initial_stress,
)
from rockfrac.case.messages import require
from rockfrac.case.program import StageSection, StopSection
from rockfrac.case.schema import Case
from rockfrac.elements.base import ElementGroup
from rockfrac.errors import CaseError
from rockfrac.fem.loads import (
    edge_pressure,
    edge_traction,
    face_pressure,
    face_traction,
    side_normals,
)
from rockfrac.mesh.mesh import Mesh
from rockfrac.mesh.topology import match, on_boundary, outer_boundary
from rockfrac.model import Model
from rockfrac.output.history import Monitor
from rockfrac.solve.newton import Measure
from rockfrac.solve.paths import PathSpec, arc_length_path, crack_path, energy_path
from rockfrac.solve.stepping import Stage
from rockfrac.values import given

COMPONENTS = {"x": 0, "y": 1, "z": 2}
EQUILIBRIUM_TOL = 1e-8  # unbalanced nodal force at t = 0, relative to the largest initial load


@dataclass
class Program:
    """Engine stages, the state at t = 0 and each stage's stop rule (None: none)."""

    stages: list[Stage]
    u0: np.ndarray
    f0: np.ndarray
    stops: list[StopSection | None]
    sections: list[StageSection]
    aliases: bool = False  # the paper's u_axial, F_axial columns (the [loading] form)
    notes: list[str] = field(default_factory=list)  # what run.log should say about the set-up


def expand_loading(case: Case, mesh: Mesh, path: str) -> list[tuple[StageSection, str]]:
    """[loading] as stages: confinement (supports held, pressure on the sides), then one axial stage
    per target (the top shortened); each with the source a failure names."""
    load = given(case.loading, "[loading]")
    for key in ("support", "pin", "axial"):
        require([getattr(load, key)], mesh.node_sets, "node group", f"[loading] {key}", path)
    held = [(load.support, {"y": 0.0}), (load.pin, {"x": 0.0}), (load.axial, {"y": 0.0})]
    if mesh.dim == 3:  # plane strain: both out-of-plane faces held in their normal direction
        require(["back", "front"], mesh.node_sets, "node group",
                "[mesh] (3D plane strain needs the out-of-plane faces)", path)
        held += [("back", {"z": 0.0}), ("front", {"z": 0.0})]
    displacement: dict[str, dict] = {}
    for group, comps in held:  # one group may be named twice (pin = support: a base held in x and y)
        displacement.setdefault(group, {}).update(comps)
    sides = mesh.edge_sets if mesh.dim == 2 else mesh.face_sets
    require(load.pressure, sides, "boundary group", "[loading] pressure", path)
    out = [(StageSection.model_construct(name="confinement", steps=load.confinement_steps, control="load",
                                         displacement=displacement,
                                         pressure={p: load.confinement for p in load.pressure}, traction={},
                                         gravity=None, in_situ={}, stop=None, path_increment=None, max_steps=None),
            f"{path}: [loading] confinement = {load.confinement:g} Pa")]
    stop = (StopSection.model_construct(quantity="F_axial", below_peak_fraction=load.stop_below_peak_fraction)
            if load.stop_below_peak_fraction is not None else None)
    path_control = load.control is Control.path
    for k, target in enumerate(load.axial_targets):
        name = "axial" if k == 0 else f"axial {k + 1}"
        key = "axial_displacement" if len(load.axial_targets) == 1 else f"axial_displacement[{k + 1}]"
        out.append((StageSection.model_construct(
            name=name, steps=load.axial_steps, control="path" if path_control else "load",
            path_increment=load.path_increment, max_steps=load.max_steps,
            displacement={load.axial: {"y": -target}}, pressure={}, traction={}, gravity=None, in_situ={},
            stop=stop), f"{path}: [loading] {key} = {target:g} m"))
    return out


def _sides(mesh: Mesh, name: str, key: str, path: str) -> np.ndarray:
    """The boundary edges (2D) or faces (3D) of a group, checked to be on the boundary."""
    sets = mesh.edge_sets if mesh.dim == 2 else mesh.face_sets
    require([name], sets, "boundary group", key, path)
    sides = sets[name]
    inside = ~on_boundary(mesh, sides)
    if inside.any():
        raise CaseError(f"{path}: {key}: {name!r} is not (all) on the boundary ({int(inside.sum())} of its "
                        f"{len(sides)} sides are inside the body); loads act on boundary edges or faces")
    return sides


def _vector(values, dim: int, key: str, path: str) -> np.ndarray:
    v = np.asarray(values, dtype=float)
    if v.shape != (dim,):
        raise CaseError(f"{path}: {key}: {v.size} components; this {dim}D mesh needs {dim}")
    return v


def path_spec(stage: StageSection, surfaces: list[ElementGroup], mesh: Mesh, model: Model, monitors: list[Monitor],
              thickness: float, key: str, path: str) -> PathSpec | None:
    """The stage's path following: on the discontinuities' jumps (cohesive pairs or embedded cells),
    on an opening monitor, on the arc length or on the energy released. On a distributed model the
    jumps' measure averages over the points of every rank."""
    n_dofs = model.n_dofs

    def active() -> bool:
        return model.reduce_any(any(g.path_active() for g in surfaces))

    if stage.control == "load":
        return None
    if stage.max_steps is None:
        raise CaseError(f"{path}: {key}: max_steps is not resolved")
    if stage.control == "arc_length":
        return arc_length_path(model.n_u, stage.path_increment, stage.max_steps, model, model.n_u_global)
    if stage.control == "energy":
        if stage.path_increment is None:
            raise CaseError(f"{path}: {key} path_increment: control = 'energy' needs the energy released per step "
                            "[J/m in 2D (per unit thickness), J in 3D]")
        return energy_path(model.n_u, thickness, stage.path_increment, active, stage.max_steps, model)
    if stage.control == "opening":
        found = {m.name: m for m in monitors}
        m = found.get(stage.monitor or "")
        if m is None or m.direction is None:
            openings = sorted(n for n, v in found.items() if v.direction is not None)
            raise CaseError(f"{path}: {key} monitor = {stage.monitor!r}: not an opening monitor of [[monitors]] "
                            f"(openings: {', '.join(openings) or 'none'})")
        return crack_path(lambda: opening_measure(m, mesh.dim, n_dofs, model), stage.path_increment, lambda: True,
                          stage.max_steps, f"opening {m.name}", rigid_ok=True)
    if not surfaces:
        raise CaseError(f"{path}: {key} control = 'path' needs a cohesive surface or an [embedded] section")
    if stage.path_increment is None:
        raise CaseError(f"{path}: {key}: path_increment is not resolved")

    def measure() -> Measure | None:
        if model.distributed:
            return distributed_measure()
        found = [(m, g.path_weight()) for g in surfaces if (m := g.path_measure(n_dofs)) is not None]
        if len(found) <= 1:
            return found[0][0] if found else None
        parts = [m for m, _ in found]
        w = np.array([wt for _, wt in found], dtype=float)
        w /= w.sum()

        def combined(u: np.ndarray) -> tuple[float, np.ndarray]:
            values, grads = zip(*(m(u) for m in parts))
            return float(np.dot(w, values)), sum(wi * gi for wi, gi in zip(w, grads))

        return combined

    def distributed_measure() -> Measure | None:
        """The serial measure from the ranks' parts: each group's average over its points of every
        rank (by their integration weights), the groups combined by their points' counts."""
        found = [(k, m) for k, g in enumerate(surfaces) if (m := g.path_measure(n_dofs)) is not None]
        counts, masses = np.zeros(len(surfaces)), np.zeros(len(surfaces))
        for k, _ in found:
            counts[k], masses[k] = surfaces[k].path_count(), surfaces[k].measure_mass()
        total_counts, total_masses = model.reduce_sum(counts), model.reduce_sum(masses)
        has = {k for k, _ in found}
        found_any = model.reduce_sum(np.array([1.0 if k in has else 0.0 for k in range(len(surfaces))]))
        total_counts = np.where(found_any > 0.0, np.maximum(total_counts, 1.0), 0.0)  # each group's path_weight
        if total_counts.sum() == 0.0:
            return None
        coef = [(m, total_counts[k] / total_counts.sum() * masses[k] / total_masses[k]) for k, m in found
                if masses[k] > 0.0]

        def combined(u: np.ndarray) -> tuple[float, np.ndarray]:
            value, grad = 0.0, np.zeros(n_dofs)  # this rank's part of the gradient
            for m, c in coef:
                v, gr = m(u)
                value += c * v
                grad += c * gr
            return model.reduce_sum(value), grad

        return combined

    return crack_path(measure, stage.path_increment, active, stage.max_steps, rigid_ok=True)


def _check_still_supports(presc: dict[int, float], held: dict[int, float] | None, key: str, path: str,
                          model: Model) -> None:
    """control = 'energy' counts the work of the forces alone: every prescribed displacement of the
    stage must be 0 from its start (the supports' reactions then do no work); on every MPI rank at
    once, the dof named by its number in the whole model."""
    moving = sorted(d for d, v in presc.items() if v != 0.0 or (held is not None and held.get(d) != 0.0))
    failure = None
    if moving:
        failure = (f"{path}: {key} control = 'energy': the stage moves prescribed displacements (dof "
                   f"{int(model.whole_dofs(np.array(moving[:1]))[0])}{' and others' if len(moving) > 1 else ''}: "
                   "nonzero, or not held at 0 before the stage); the energy released is that of forces on supports "
                   "held at 0. Drive a displacement-loaded stage with control = 'path', 'opening' or 'arc_length'")
    failure = model.agree(failure)
    if failure is not None:
        raise CaseError(failure)


def opening_measure(m: Monitor, dim: int, n_dofs: int, model: Model | None = None) -> Measure:
    """g(u) = e . (mean u of nodes[1] - mean u of nodes[0]): the monitor's opening [m], linear in u
    (on a distributed ``model``, the gradient over each rank's owned dofs, the value summed)."""
    assert m.direction is not None
    grad = np.zeros(n_dofs)
    for k, (sign, ids) in enumerate(((-1.0, m.nodes[0]), (1.0, m.nodes[1]))):
        for a in range(dim):
            dofs, _ = model.local_dofs(ids * dim + a) if model is not None else (ids * dim + a, None)
            np.add.at(grad, dofs, sign * m.direction[a] / m.count(k))
    if model is not None and model.distributed:
        part = model.owned(grad)
        return lambda u: (model.reduce_sum(float(part @ u)), part)
    return lambda u: (float(grad @ u), grad)


def _source(stage: StageSection, key: str, path: str) -> str:
    parts = [f"displacement {g}.{c} = {v if isinstance(v, str) else format(v, 'g')}"
             for g, comps in stage.displacement.items() for c, v in comps.items()]
    parts += [f"pressure {g} = {v:g} Pa" for g, v in stage.pressure.items()]
    parts += [f"traction {g} = {list(v)} Pa" for g, v in stage.traction.items()]
    if stage.gravity is not None:
        parts.append(f"gravity = {list(stage.gravity)} m/s^2")
    parts += [f"in_situ {g} = {v:g}" for g, v in stage.in_situ.items()]
    return f"{path}: {key} ({'; '.join(parts) or 'held loads'})"


def _stage_sections(case: Case, mesh: Mesh, path: str) -> tuple[list[tuple[StageSection, str]], list[str]]:
    """The loading program's stages (the [loading] form expanded) with their sources, and their keys."""
    if case.loading is not None:
        pairs = expand_loading(case, mesh, path)
        return pairs, ["[loading]"] * len(pairs)
    keys = [f"[stages {k + 1}]" for k in range(len(case.stage_sections))]
    return [(st, _source(st, key, path)) for st, key in zip(case.stage_sections, keys)], keys


def check_boundary_groups(case: Case, mesh: Mesh, path: str) -> None:
    """The groups the loading program names, checked on the whole mesh (an MPI run's rank 0, before
    it sends each rank its piece: a piece holds a group's nodes and sides in part): node groups of
    prescribed displacements, boundary groups of loads, in-situ groups on the outer boundary."""
    outer = outer_boundary(mesh)
    pairs, keys = _stage_sections(case, mesh, path)
    for (st, _), key in zip(pairs, keys):
        require(list(st.displacement), mesh.node_sets, "node group", f"{key} displacement", path)
        for group in st.pressure:
            _sides(mesh, group, f"{key} pressure", path)
        for group in st.traction:
            _sides(mesh, group, f"{key} traction", path)
        for group in st.in_situ if case.initial is not None and case.initial.stress else ():
            _, count = match(outer, _sides(mesh, group, f"{key} in_situ", path))
            if (count == 0).any():
                raise CaseError(f"{path}: {key} in_situ.{group}: not on the outer boundary (a crack face?)")


def build_program(case: Case, mesh: Mesh, model: Model, bulks: list, cohesives: list, thickness: float,
                  path: str, monitors: list[Monitor] | None = None,
                  minus_groups: list[np.ndarray] | None = None) -> Program:
    """The engine stages of the case's loading program and its state at t = 0 (``monitors``: found
    on the whole mesh, None: on ``mesh``; ``minus_groups``: see :func:`set_initial_stress`)."""
    dim = mesh.dim
    surfaces = cohesives or [g for g in bulks if g.kind == "embedded"]
    if monitors is None:
        monitors = resolve_monitors(case, mesh, path)
    if case.bulk is not None:
        densities = {b.region: case.bulk.density for b in bulks}
    else:
        densities = {m.region: m.density for m in case.materials or []}
    pairs, keys = _stage_sections(case, mesh, path)
    # the state at t = 0
    notes = []
    initial = None
    outer = outer_boundary(mesh)
    in_situ_factor = np.ones(outer.shape[0])
    g0 = np.zeros(dim)
    if case.initial is not None:
        if case.initial.gravity is not None:
            g0 = _vector(case.initial.gravity, dim, "[initial] gravity", path)
        if case.initial.stress:
            initial = InitialStress(case.initial.stress, [b.region for b in bulks], dim, path)
            try:
                set_initial_stress(mesh, bulks, cohesives, initial, model, minus_groups)
            except CaseError as err:
                raise CaseError(f"{path}: {err}") from None
            model.update_constant_force()
    # the loads of the rank's own cells and sides (serial: all of them), summed over the ranks below
    f_gravity0 = gravity_forces(bulks, densities, mesh, g0, "[initial] gravity", path)
    f_situ = in_situ_forces(mesh, bulks, initial, outer, in_situ_factor) if initial is not None else 0.0
    f0 = f_gravity0 + f_situ
    # the stages
    presc: dict[int, float] = {}
    pressure: dict[str, float] = {}
    traction: dict[str, np.ndarray] = {}
    gravity = g0.copy()
    stages, stops, sections = [], [], []
    for k, ((st, source), key) in enumerate(zip(pairs, keys)):
        held = dict(presc) if k > 0 else None  # the prescribed values the stage starts from (None: u = 0)
        for group, comps in st.displacement.items():
            require([group], mesh.node_sets, "node group", f"{key} displacement", path)
            nodes = mesh.node_sets[group]
            for comp, value in comps.items():
                a = COMPONENTS[comp]
                if a >= dim:
                    raise CaseError(f"{path}: {key} displacement.{group}.{comp}: a {dim}D mesh has components "
                                    f"{', '.join(list(COMPONENTS)[:dim])}")
                for d in (dim * nodes + a).tolist():
                    if value == "free":
                        presc.pop(d, None)
                    else:
                        presc[d] = float(value)
        for group, p in st.pressure.items():
            _sides(mesh, group, f"{key} pressure", path)
            traction.pop(group, None)
            pressure[group] = float(p)
        for group, t in st.traction.items():
            _sides(mesh, group, f"{key} traction", path)
            pressure.pop(group, None)
            traction[group] = _vector(t, dim, f"{key} traction.{group}", path)
        if st.gravity is not None:
            gravity = _vector(st.gravity, dim, f"{key} gravity", path)
        for group, factor in st.in_situ.items():
            if initial is None:
                raise CaseError(f"{path}: {key} in_situ: there is no in-situ stress ([initial] stress)")
            sides = _sides(mesh, group, f"{key} in_situ", path)
            row, count = match(outer, sides)
            if (count == 0).any():
                raise CaseError(f"{path}: {key} in_situ.{group}: not on the outer boundary (a crack face?)")
            in_situ_factor[row] = factor
        f_end = np.zeros(dim * mesh.n_nodes)
        surface_edges, surface_tractions = [], []  # each loaded edge (face) and its traction
        for group, p in pressure.items():
            sides = (mesh.edge_sets if dim == 2 else mesh.face_sets)[group]
            (edge_pressure if dim == 2 else face_pressure)(mesh.nodes, own_sides(mesh, bulks, sides), p, f_end)
            if sides.size:
                surface_edges.append(sides)
                surface_tractions.append(_at_nodes(-p * side_normals(mesh.nodes, sides), sides))
        for group, vec in traction.items():
            sides = (mesh.edge_sets if dim == 2 else mesh.face_sets)[group]
            (edge_traction if dim == 2 else face_traction)(mesh.nodes, own_sides(mesh, bulks, sides), vec, f_end)
            if sides.size:
                surface_edges.append(sides)
                surface_tractions.append(_at_nodes(np.broadcast_to(np.asarray(vec, dtype=float),
                                                                   (sides.shape[0], dim)), sides))
        f_end += gravity_forces(bulks, densities, mesh, gravity, f"{key} gravity", path)
        if initial is not None:
            f_end += in_situ_forces(mesh, bulks, initial, outer, in_situ_factor)
            if model.enrichment_version() is not None:  # nodal cracks: their share where they cross the boundary
                loaded, t_situ = in_situ_tractions(mesh, bulks, initial, outer, in_situ_factor)
                surface_edges.append(loaded)
                surface_tractions.append(t_situ)
        f_full = model.summed(f_end)
        dofs, values = _prescribed(model, presc)
        if st.control == "energy":
            _check_still_supports(presc, held, key, path, model)
        name = st.name or f"stage {k + 1}"
        stages.append(Stage(name, st.steps, values, f_full, path_spec(st, surfaces, mesh, model, monitors, thickness,
                                                                 key, path),
                            source=source, dirichlet=dofs,
                            surface_edges=np.vstack(surface_edges) if surface_edges else None,
                            surface_tractions=np.vstack(surface_tractions) if surface_tractions else None,
                            body_force=_body_forces(densities, gravity)))
        stops.append(st.stop)
        sections.append(st)
    u0 = model.initial_unknowns()
    f0_full = model.summed(np.atleast_1d(np.asarray(f0, dtype=float)))
    if stages and model.enrichment_version() is not None:  # nodal cracks' share at t = 0
        if initial is not None:
            edges0, tractions0 = in_situ_tractions(mesh, bulks, initial, outer, np.ones(outer.shape[0]))
            stages[0] = replace(stages[0], start_edges=edges0, start_tractions=tractions0)
        stages[0] = replace(stages[0], start_body_force=_body_forces(densities, g0))
    if initial is not None or np.any(g0):
        _check_equilibrium(model, stages[0], u0, f0_full, initial, path)
        notes.append("initial state: in equilibrium with the in-situ tractions"
                     + (" and gravity" if np.any(g0) else ""))
    if initial is not None:
        for g in model.groups:
            why = model.agree(g.initial_violation() or None)  # a point of any rank
            if why:
                raise CaseError(f"{path}: [initial] stress: {why}")
    return Program(stages, u0, f0_full, stops, sections, aliases=case.loading is not None, notes=notes)


def _prescribed(model: Model, presc: dict[int, float]) -> tuple[np.ndarray, np.ndarray]:
    """The prescribed dofs (global dof -> value) in the model's numbering, sorted, and their values (an
    MPI rank keeps those of its local dofs)."""
    dofs = np.array(sorted(presc), dtype=np.int64)
    values = np.array([presc[d] for d in dofs.tolist()])
    local, held = model.local_dofs(dofs)
    order = np.argsort(local, kind="stable")
    return local[order], values[held][order]


def _at_nodes(tractions: np.ndarray, sides: np.ndarray) -> np.ndarray:
    """Uniform tractions per side (m, dim) as their values at the side's nodes (m, s, dim)."""
    return np.repeat(tractions[:, None, :], sides.shape[1], axis=1)


def _body_forces(densities: dict[str, float | None], g: np.ndarray) -> dict[str, np.ndarray] | None:
    """Gravity's body force [N/m^3] per region with a density (None: no gravity)."""
    if not np.any(g):
        return None
    return {r: rho * g for r, rho in densities.items() if rho is not None}


def _check_equilibrium(model: Model, first: Stage, u0: np.ndarray, f0: np.ndarray, initial: InitialStress | None,
                       path: str) -> None:
    """The state at t = 0 must be in equilibrium on the dofs the first stage leaves free."""
    if first.dirichlet is not None:
        model.set_dirichlet(first.dirichlet)
    model.begin_step()
    asm = model.assemble(u0, u0, f0)
    r = model.owned(asm.residual)[model.free]  # each dof on one rank
    scale = max(float(model.reduce_max(np.abs(f0).max(initial=0.0))), 1e-30)  # every rank's loads
    mine = float(np.abs(r).max(initial=0.0))
    worst = model.reduce_max(mine)
    failure = None
    if worst > EQUILIBRIUM_TOL * scale and mine == worst:
        i = int(model.global_dofs(model.free[np.argmax(np.abs(r))]))
        failure = (f"{path}: [initial]: the state at t = 0 is not in equilibrium: an unbalanced force of "
                   f"{worst:.4g} N/m at dof {i} (the largest initial load is {scale:.4g} N/m); an in-situ stress "
                   "that varies with elevation needs the gravity that balances it (d sigma_yy / dy = rho g_y "
                   "with [initial] gravity and the regions' density), and it must be continuous across "
                   "regions where they touch")
    failure = model.agree(failure)  # every rank raises the first rank's
    if failure is not None:
        raise CaseError(failure)


def _nearest(nodes: np.ndarray, x: list[float], key: str, path: str) -> tuple[int, float]:
    p = np.asarray(x, dtype=float)
    if p.shape[0] != nodes.shape[1]:
        raise CaseError(f"{path}: {key}: {p.shape[0]} coordinates; this {nodes.shape[1]}D mesh needs {nodes.shape[1]}")
    d = np.linalg.norm(nodes - p[None, :], axis=1)
    i = int(np.argmin(d))
    return i, float(d[i])


def resolve_monitors(case: Case, mesh: Mesh, path: str) -> list[Monitor]:
    """The [[monitors]] on the mesh: nearest nodes of points, node groups of openings."""
    out = []
    axes = "xyz"[: mesh.dim]
    for k, m in enumerate(case.monitors or []):
        key = f"[monitors {k + 1}]"
        if m.kind == "displacement":
            i, d = _nearest(mesh.nodes, given(m.at), f"{key} at", path)
            out.append(Monitor(m.name, [f"{m.name}_{a}" for a in axes], (np.array([i]),), None,
                               f"monitor {m.name}: node {i}, {d:.3g} m from the point asked for"))
        elif m.points is not None:
            (i, d1), (j, d2) = (_nearest(mesh.nodes, p, f"{key} points", path) for p in m.points)
            e = np.asarray(m.points[1], float) - np.asarray(m.points[0], float)
            out.append(Monitor(m.name, [m.name], (np.array([i]), np.array([j])), e / np.linalg.norm(e),
                               f"monitor {m.name}: opening of node {j} against node {i} ({d1:.3g} and {d2:.3g} m "
                               "from the points asked for)"))
        else:
            groups = given(m.groups, f"{key} groups")
            require(groups, mesh.node_sets, "node group", f"{key} groups", path)
            e = _vector(m.direction, mesh.dim, f"{key} direction", path)
            out.append(Monitor(m.name, [m.name], tuple(np.asarray(mesh.node_sets[g]) for g in groups),
                               e / np.linalg.norm(e), f"monitor {m.name}: opening of {groups[1]!r} against "
                               f"{groups[0]!r} along {list(e / np.linalg.norm(e))}"))
    return out
