"""Run a case on the ranks of an MPI communicator: the same stepping, Newton and path following as a
serial run, on a distributed model (:mod:`rockfrac.parallel.model`).

Rank 0 makes the split mesh, partitions it (METIS) and sends every rank its piece of it
(:mod:`rockfrac.case.shares`); every rank builds its own groups on its piece and takes every step
with the others (each collective call in the same order).
The converged steps come to ``on_step`` on every rank with the displacements and internal forces
on the rank's local dofs; :meth:`Layout.gather` assembles a whole vector.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np

from rockfrac.case.build import Built, Distribution, build
from rockfrac.case.shares import Share
from rockfrac.case.schema import Case, load_case
from rockfrac.elements.base import ElementGroup
from rockfrac.errors import CaseError
from rockfrac.elements.ede_nodal_parts import HeldEnrichment
from rockfrac.mesh.mesh import Mesh
from rockfrac.mesh.partition import Partition, RankPartition, partition
from rockfrac.parallel.model import DistributedModel
from rockfrac.parallel.solvers import distributed_solver
from rockfrac.runner import engine_options
from rockfrac.solve.stepping import RunResult, StepInfo, run_stages


def distribution(comm) -> Distribution:
    """How ``comm``'s ranks share a case: rank 0 makes the whole split mesh, partitions it (METIS, one
    part per rank) and sends each rank its share (its piece of the mesh); an input error found
    there is raised on every rank."""
    from mpi4py.util import pkl5

    rank, size = comm.Get_rank(), comm.Get_size()

    def split(mesh: Mesh) -> Partition:
        return partition(mesh, size)

    def share(make) -> Share:
        """Rank 0 makes the whole mesh and cuts the shares, sending each as it is cut (it holds one
        at a time beside its own); an input error is raised on every rank. A share travels pickled
        with protocol 5, its arrays as out-of-band buffers (``mpi4py.util.pkl5``: no copy into the
        pickle, and a piece of more than 2 GiB goes as one message)."""
        failure = None
        if rank == 0:
            try:
                whole, shares = make(size, split)
                mine = next(shares)
            except (CaseError, ValueError) as err:
                failure = err
        failure = comm.bcast(failure, root=0)  # every rank raises it, none waits for the others
        if failure is not None:
            raise failure
        large = pkl5.Intracomm(comm)
        if rank == 0:
            for r in range(1, size):
                large.send(next(shares), dest=r)
            mine.whole = whole
            return mine
        return large.recv(source=0)

    def make_model(mesh: Mesh, groups: list[ElementGroup], part: RankPartition) -> DistributedModel:
        return DistributedModel(part.n_nodes, groups, np.zeros(0, dtype=np.int64), dim=mesh.dim, comm=comm,
                                partition=part, rank=rank, nodes=mesh.nodes)

    return Distribution(share, rank, make_model, distributed_solver, comm)


def build_distributed(case: Case | str | Path, comm, path_label: str | None = None) -> Built:
    """This rank's share of the case (CaseError, on every rank, for a case that cannot be split)."""
    label = path_label or (str(case) if not isinstance(case, Case) else "<case>")
    if not isinstance(case, Case):
        case = load_case(case)
    return build(case, label, distribution(comm))


def run_distributed(built: Built, on_step: Callable[[StepInfo], None],
                    log: Callable[[str], None] = lambda s: None) -> RunResult:
    """Run the stages of a distributed build with the case's [solver] options and its linear solver
    ('auto': MUMPS's LU, or GMRES + GAMG on a large 3D model)."""
    newton, stepping = engine_options(built)
    solver = distributed_solver(built.case.solver.linear.value, built.model.n_dofs_global, built.mesh.dim,
                                any(isinstance(g, HeldEnrichment) for g in built.model.groups))
    log(f"linear solver: {solver.name} on {built.model.comm.Get_size()} ranks")  # type: ignore[attr-defined]
    result = run_stages(built.model, built.stages, solver, newton, stepping, on_step, log,
                        u0=built.program.u0, f0=built.program.f0)
    for note in solver.notes():
        log(f"linear solver: {note}")
    return result
