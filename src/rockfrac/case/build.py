"""Turn a validated Case into a Model, its loading program and the quantities to report.

Every input problem (a region or boundary group the mesh does not have, an inverted cell, an
initial state out of equilibrium...) surfaces here as a CaseError, before any step is taken.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from rockfrac.case.build_groups import (  # noqa: F401 (re-exported: the case -> objects helpers)
    AUGMENTATION_SAFETY,
    check_cell_multipliers,
    cohesive_groups,
    cut_given_cracks,
    default_augmentation,
    drucker_prager_of,
    embedded_law,
    law_of_section,
    make_bulk_groups,
    set_points,
    stiffest_modulus,
)
from rockfrac.case.build_mesh import insert_cohesive, make_mesh, mean_cell_size  # noqa: F401
from rockfrac.case.build_program import Program, build_program, resolve_monitors
from rockfrac.case.cohesive_section import CohesiveForm
from rockfrac.case.program import StageSection
from rockfrac.case.schema import Case
from rockfrac.case.shares import Share, cut_shares
from rockfrac.elements.base import ElementGroup
from rockfrac.elements.cse_groups import CohesiveEP, CohesiveRP
from rockfrac.elements.ede import EmbeddedDruckerPrager
from rockfrac.elements.ede_nodal_parts import HeldEnrichment
from rockfrac.elements.solid import SolidGroup
from rockfrac.errors import CaseError
from rockfrac.mesh import Mesh
from rockfrac.mesh.interfaces import tied_nodes
from rockfrac.mesh.partition import Partition, RankPartition
from rockfrac.output.history import Monitor
from rockfrac.model import Model
from rockfrac.solve.stepping import Stage


@dataclass(frozen=True)
class Distribution:
    """One MPI rank's share of a run (:mod:`rockfrac.parallel`): its :class:`Share` (rank 0 makes the
    whole mesh and every rank's share from it, ``share(make)``: ``make(n_ranks, split)`` on rank 0),
    this rank, and the model over its elements."""

    share: Callable[[Callable[[int, Callable[[Mesh], Partition]], tuple[Mesh, Iterator[Share]]]], Share]
    rank: int
    make_model: Callable[[Mesh, list[ElementGroup], RankPartition], Model]
    make_solver: Callable[[str, int, int, bool], Any]  # [solver] linear, dofs, dimension, nodal cracks -> solver
    exchange: Any = None  # the ranks' allgather, before the model exists (rockfrac.elements.ede_paths.Exchange)


@dataclass
class Built:
    """Everything a run needs: the model, its loading program and the groups by kind."""

    case: Case
    mesh: Mesh
    model: Model
    program: Program
    thickness: float  # forces are reported per unit thickness: 1 in 2D, T for the plane-strain hex8 [m]
    bulks: list[SolidGroup] = field(default_factory=list)  # one group per material region
    cohesives: list[CohesiveEP | CohesiveRP] = field(default_factory=list)  # one CSE group per cohesive set
    partition: RankPartition | None = None  # a distributed run's: the groups hold this rank's elements only
    monitors: list[Monitor] = field(default_factory=list)  # [[monitors]] on the mesh's nodes
    whole: Mesh | None = None  # the whole mesh (an MPI run: on rank 0 only; ``mesh`` is the rank's piece)
    loops: list[np.ndarray | None] | None = None  # an MPI rank's: each set's points on loops of pairs (rank 0's)

    @property
    def stages(self) -> list[Stage]:
        return self.program.stages

    @property
    def top_y_dofs(self) -> np.ndarray:
        """The paper form's axial dofs (y of [loading] axial): F_axial is their reaction."""
        load = self.case.loading
        if load is None:
            raise AttributeError("a [[stages]] case has no axial group")
        return self.mesh.dim * self.mesh.node_sets[load.axial] + 1

    @property
    def axial_count(self) -> int | None:
        """The paper form's axial nodes in the whole mesh (None: a [[stages]] case)."""
        load = self.case.loading
        if load is None:
            return None
        whole = self.mesh.place
        return whole.node_set_sizes[load.axial] if whole is not None else int(self.mesh.node_sets[load.axial].shape[0])

    @property
    def bulk(self) -> SolidGroup:
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


def _displacement_changes(stages: list[StageSection]) -> list[float]:
    """Largest change of a prescribed displacement component in each stage [m]."""
    now: dict[tuple[str, str], float] = {}
    out = []
    for st in stages:
        change = 0.0
        for group, comps in st.displacement.items():
            for comp, value in comps.items():
                if value == "free":
                    now.pop((group, comp), None)
                    continue
                change = max(change, abs(float(value) - now.get((group, comp), 0.0)))
                now[(group, comp)] = float(value)
        out.append(change)
    return out


def resolve(case: Case, path: str = "<case>") -> Case:
    """Fill every default, including those that depend on the case (path control, RP augmentation)."""
    case = case.resolved()
    load = case.loading
    if load is not None and load.control.value == "path":
        nominal = abs(load.axial_targets[0]) / load.axial_steps
        load = load.model_copy(update={"path_increment": load.path_increment or nominal,
                                       "max_steps": load.max_steps or 20 * load.axial_steps})
        case = case.model_copy(update={"loading": load})
    if case.stages is not None and any(s.control != "load" for s in case.stages):
        stages = []
        for k, (st, change) in enumerate(zip(case.stages, _displacement_changes(case.stages))):
            if st.control == "path" and st.path_increment is None and change == 0.0:
                raise CaseError(f"{path}: [stages {k + 1}] path_increment: needed, since the stage prescribes no "
                                "displacement change to take the nominal increment from")
            if st.control == "path":
                st = st.model_copy(update={"path_increment": st.path_increment or change / st.steps})
            if st.control != "load":
                st = st.model_copy(update={"max_steps": st.max_steps or 20 * st.steps})
            stages.append(st)
        case = case.model_copy(update={"stages": stages})
    if not any(c.form is CohesiveForm.rp and c.augmentation is None for c in case.cohesive_sets):
        return case
    mesh = make_mesh(case, path)
    sets = [c.model_copy(update={"augmentation": c.augmentation or default_augmentation(case, mesh, c)})
            if c.form is CohesiveForm.rp else c for c in case.cohesive_sets]
    return case.model_copy(update={"cohesive": sets})


def build(case: Case, path: str = "<case>", distribution: Distribution | None = None) -> Built:
    """The model: mesh (split where cohesive surfaces go), bulk and surface groups, the loading program.

    distribution: build one MPI rank's model on its piece of the mesh, its groups holding the
    elements of its part only (rank 0 makes the whole mesh and every rank's share).
    """
    share: Share | None = None
    if distribution is None:
        case = resolve(case, path)
        mesh, set_cells = insert_cohesive(case, make_mesh(case, path), path)
    else:
        share = distribution.share(lambda n, split: cut_shares(resolve(case, path), path, n, split))
        case, mesh, set_cells = share.case, share.mesh, []
    part = share.partition if share is not None else None
    rank = distribution.rank if distribution is not None else 0
    owned = part.cell_part == rank if part is not None else None
    try:
        bulks = make_bulk_groups(case, mesh, path, owned, distribution.exchange if distribution is not None else None,
                                 rank, share.cell_serial if share is not None else None,
                                 share.enrichment[0] if share is not None and share.enrichment is not None else None)
    except CaseError:
        raise
    except ValueError as err:
        raise CaseError(f"{path}: [mesh]: {err}") from None
    cohesives: list = []
    extra_part = []  # the owning rank of each rigid-plastic point's multipliers, set after set
    extra_counts, own_extras, offset = [], [], 0  # or each set's count on every rank, and this rank's own
    smoothed = share is None and any(section.smoothing is not None for section in case.cohesive_sets)
    root = tied_nodes(mesh) if smoothed else None  # each copy's node, made once for every smoothed set
    for k, section in enumerate(case.cohesive_sets):
        junction = None
        if share is None:
            cells = set_cells[k]
            points = set_points(section, mesh, cells, root)
            check_cell_multipliers(section, points, f"cohesive {k + 1}", path)
            total = points.n
        else:  # the rank's points (on the rank of their first interface cell), from rank 0
            mine = share.cohesive[k]
            points, total, junction = mine.points, mine.total, mine.junction
            if mine.owners is not None:
                extra_part.append(mine.owners)
        groups = cohesive_groups(section, points, mesh, f"cohesive {k + 1}", path, case.solver.fallback, junction)
        for g in groups:
            if isinstance(g, CohesiveRP):  # the multipliers are numbered over the whole set, on every rank
                g.total_points = total if share is not None else g.points.n
                counts = share.cohesive[k].owner_counts if share is not None else None
                if counts is not None:
                    extra_counts.append(counts)
                    own_extras.append(offset + g.multiplier_blocks())
                    offset += g.extra_span() // g.dim
        cohesives += groups
    extras = [c for g in bulks for c in g.companions()]  # a nodal crack's cut cells and unknowns
    held = [g for g in extras if isinstance(g, HeldEnrichment)]
    if part is not None and held:  # each node's q's on the rank of its dofs (rank 0 found them)
        assert share is not None and share.enrichment is not None
        owner = share.enrichment[1]
        held[0].hold_only(np.flatnonzero(owner == rank))
        extra_part.append(owner)
    if part is not None and extra_part:
        part = part.with_extras(np.concatenate(extra_part))
    elif part is not None and extra_counts:  # a rank's piece: its own multipliers, the others' counted
        part = part.with_own_extras(np.sum(extra_counts, axis=0), np.concatenate(own_extras))
    if distribution is None or part is None:
        model = Model(mesh.n_nodes, bulks + cohesives + extras, np.zeros(0, dtype=np.int64), dim=mesh.dim)
    else:
        model = distribution.make_model(mesh, bulks + cohesives + extras, part)
    thickness = (case.mesh.resolved().thickness or 1.0) if mesh.dim == 3 else 1.0
    monitors = share.monitors if share is not None else resolve_monitors(case, mesh, path)
    minus = [c.minus_group for c in share.cohesive] if share is not None else None
    program = build_program(case, mesh, model, bulks, cohesives, thickness, path, monitors, minus)
    cut_given_cracks(case, bulks, mesh, path)  # after the state at t = 0 (build_program's in-situ stress)
    if program.stages and program.stages[0].dirichlet is not None:
        model.set_dirichlet(program.stages[0].dirichlet)
    return Built(case, mesh, model, program, thickness, bulks, cohesives, part, monitors,
                 share.whole if share is not None else mesh,
                 [c.on_loops for c in share.cohesive] if share is not None else None)
