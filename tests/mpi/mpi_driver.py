"""What the MPI tests run under ``mpiexec -n N``: ``python mpi_driver.py TASK CASE.json OUT.npz``.

CASE.json holds a case dictionary (paths in it absolute). Rank 0 writes the results into OUT.npz;
a CaseError is written there as ``error`` (raised on every rank, so none waits for the others).
Tasks:
- ``history``: run the case; per converged step its load factor, Newton iterations, control and
  the displacements and internal forces gathered whole.
- ``histories``: ``history`` for each case of the case file's ``"cases"`` (name -> case) in this one
  launch, its results under ``NAME.KEY``; a CaseError is that case's ``NAME.error``.
- ``history_auto_amg``: ``history`` with 'auto' taking its large-3D choice at any size (GMRES + GAMG
  handing over to MUMPS's LU), and the solver's name.
- ``history_short_room``: ``history`` with MUMPS's LU of saddle points started from its default
  workspace (ICNTL(14) = 20 %), and the run's log lines.
- ``system``: assemble at a displacement field given in the case file's ``"u"``; the global
  tangent (Dirichlet rows of the first stage applied) in rockfrac's numbering, gathered from every
  rank's owned rows, and the residual; the ownership of cells and interface cells, and the ghost
  values after a scatter.
- ``traffic``: run the case, then write the last step's ParaView piece and a checkpoint on every
  rank while counting what each rank passes to MPI (pickled bytes of mpi4py's lowercase calls, the
  buffers of its uppercase ones) and the entries it asks of the other ranks (``values_at``); the
  largest rank's bytes, and the model's dofs.
"""

from __future__ import annotations

import pickle
import tempfile
from pathlib import Path

import json
import sys

import numpy as np
from mpi4py import MPI

from rockfrac.case.schema import parse_case
from rockfrac.errors import CaseError
from rockfrac.parallel.run import build_distributed, run_distributed


def history(built, comm) -> dict:
    lay = built.model.layout
    rows: dict[str, list] = {"lam": [], "iterations": [], "path": [], "u": [], "f_int": []}

    def on_step(info) -> None:
        rows["lam"].append(info.load_factor)
        rows["iterations"].append(info.newton.iterations)
        rows["path"].append(info.controlled_by == "path")
        rows["u"].append(lay.gather(info.u))
        rows["f_int"].append(lay.gather(info.f_int))

    log: list[str] = []
    result = run_distributed(built, on_step, log.append)
    out = {k: np.array(v) for k, v in rows.items()}
    # each rank's piece of the mesh, against the whole, and the cells its crack-path registry sees
    paths = {id(g.paths): g.paths for g in built.embeddeds}
    seen = sum(p.ids.size for p in paths.values())
    piece = comm.gather((built.mesh.cells.shape[0], built.mesh.place.n_cells, seen), root=0)
    if comm.rank == 0:
        out["piece_cells"], out["whole_cells"], out["seen_cells"] = (np.array(v) for v in zip(*piece))
    out["message"] = np.array(result.message)
    out["solver_line"] = np.array(log[0] if log else "")
    out["log"] = np.array("\n".join(log))
    return out


def system(built, comm, u: np.ndarray) -> dict:
    model, lay = built.model, built.model.layout
    model.set_dirichlet(built.stages[0].dirichlet)
    model.begin_step()
    place = built.mesh.place  # the rank's piece of the mesh in the whole one
    dim = built.mesh.dim
    u = model.localized(u.reshape(-1, dim)[place.nodes].ravel())  # the rank's local entries of the whole vector
    asm = model.assemble(u, np.zeros(model.n_dofs), np.zeros(model.n_dofs))  # from the virgin state
    a = model.apply_dirichlet(asm.matrix).mat
    indptr, cols, vals = a.getValuesCSR()
    rows = lay.owned[np.repeat(np.arange(indptr.shape[0] - 1), np.diff(indptr))]
    old = np.empty(lay.n, dtype=np.int64)  # PETSc index -> rockfrac dof, from every rank's local dofs
    for petsc_rows, dofs in comm.allgather((lay.local_petsc, lay.local)):
        old[petsc_rows] = dofs
    parts = comm.gather((rows, old[cols], vals), root=0)
    cells = place.cells[np.concatenate([g.cell_ids for g in built.bulks] + [np.zeros(0, dtype=np.int64)])]
    pairs = place.nodes[np.concatenate([g.points.minus for g in built.cohesives] + [np.zeros(0, dtype=np.int64)])]
    owned_cells = comm.gather(cells, root=0)
    owned_pairs = comm.gather(pairs, root=0)
    # ghosts: a vector whose owned entries are 1 + the global dof, scattered to every local entry
    probe = lay.from_vec(lay.to_vec(np.where(lay.owned_mask, lay.local + 1.0, np.nan)))
    ghost_error = comm.allreduce(float(np.abs(probe - (lay.local + 1.0)).max(initial=0.0)), op=MPI.MAX)
    local_vectors = comm.allreduce(int(model.n_dofs != lay.local.shape[0] or asm.residual.shape != (model.n_dofs,)))
    n_ghosts = comm.gather(int(lay.local.shape[0] - lay.owned.shape[0]), root=0)
    n_local = comm.gather(int(model.n_dofs), root=0)
    n_global = comm.gather(int(model.n_dofs_global), root=0)  # what sizes the solver's choice, alike
    # each rank's piece of the mesh, and who holds the whole one
    piece = comm.gather((built.mesh.cells.shape[0], built.mesh.n_nodes, built.whole is not None), root=0)
    # the rank's matrix is numbered on its local dofs only: its pattern has a row per local dof
    rows_of_pattern = comm.allreduce(int(model.pattern.n != lay.local.shape[0]))
    out = {"residual": lay.gather(asm.residual), "ghost_error": np.array(ghost_error),
           "pattern_not_local": np.array(rows_of_pattern), "vectors_not_local": np.array(local_vectors)}
    if comm.rank == 0:
        out["rows"] = np.concatenate([p[0] for p in parts])
        out["cols"] = np.concatenate([p[1] for p in parts])
        out["vals"] = np.concatenate([p[2] for p in parts])
        out["cells"] = np.concatenate(owned_cells)
        out["pairs"] = np.concatenate(owned_pairs)
        out["n_ghosts"] = np.array(n_ghosts)
        out["n_local"] = np.array(n_local)
        out["n_global"] = np.array(n_global)
        out["piece_cells"], out["piece_nodes"], out["holds_whole"] = (np.array(v) for v in zip(*piece))
        out["n_nodes"] = np.array(place.n_nodes)
        out["n_if_cells"] = np.array(place.n_interfaces)
        out["n_cells"] = np.array(place.n_cells)
    return out


def elimination(built, comm) -> dict:
    """One local solve (rockfrac.solve.elimination) from the virgin state with two displacement dofs
    owned by two ranks moved by 1e-6 m: the whole vectors before and
    after, the unknowns solved for and the local residual's norm before and after."""
    from rockfrac.solve.elimination import eliminate

    model, lay = built.model, built.model.layout
    model.set_dirichlet(built.stages[0].dirichlet)
    model.begin_step()
    free = model.free[model.free < model.n_u]
    ghosts = model.global_dofs(free[~lay.owned_mask[free]])  # free displacements held here, owned elsewhere
    mine = model.global_dofs(free[lay.owned_mask[free]])
    # the first rank with a ghost: that ghost, owned by another rank, and its own first free dof
    dofs = next((int(g[0]), int(m[0])) for g, m in comm.allgather((ghosts, mine)) if g.size)
    whole = np.zeros(lay.n)
    whole[list(dofs)] = 1e-6
    u = whole[model.global_dofs(np.arange(model.n_dofs))]
    zero = np.zeros(model.n_dofs)
    got = eliminate(model, u, zero, zero, model.assemble(u, zero, zero))
    assert got is not None
    return {"dofs": np.array(dofs), "u_before": whole, "u_after": lay.gather(got.u), "unknowns": got.unknowns,
            "before": np.array(got.before), "after": np.array(got.after)}


def histories(cases: dict, comm, case_file: str) -> dict:
    out = {}
    for name, data in cases.items():
        try:
            result = history(build_distributed(parse_case(data, f"{case_file} [{name}]"), comm, case_file), comm)
        except CaseError as err:
            result = {"error": np.array(str(err))}
        out.update({f"{name}.{key}": value for key, value in result.items()})
    return out


class CountingComm:
    """An mpi4py communicator that counts the bytes this rank passes to it."""

    def __init__(self, comm):
        self.comm, self.sent = comm, 0

    def __getattr__(self, name):
        call = getattr(self.comm, name)
        if not callable(call) or name.startswith("Get"):
            return call

        def counted(*args, **kwargs):
            for a in args:
                self.sent += a.nbytes if isinstance(a, np.ndarray) else len(pickle.dumps(a))
            return call(*args, **kwargs)

        return counted


def traffic(built, comm) -> dict:
    from rockfrac.output.fields import step_piece
    from rockfrac.output.observers import Checkpoints, Step

    last = []

    def keep(info) -> None:
        last[:] = [info]

    run_distributed(built, keep)
    info, model = last[0], built.model
    counting = CountingComm(model.comm)
    asked = [0]
    values_at = model.values_at

    def counted_values_at(x, dofs):
        asked[0] += len(dofs)
        return values_at(x, dofs)

    model.comm = model.layout.comm = counting
    model.values_at = counted_values_at
    piece = step_piece(built, info.u)
    piece_bytes, counting.sent = counting.sent, 0
    folder = Path(comm.bcast(tempfile.mkdtemp() if comm.rank == 0 else None, root=0))
    history = type("History", (), {"digest": staticmethod(lambda: "")})()
    Checkpoints(folder, 1, model, dict, history, "", lambda s: None, comm.rank).step(Step(info, {}, None))
    model.comm = model.layout.comm = counting.comm
    checkpoint_bytes = counting.sent
    worst = np.max(comm.allgather([piece_bytes, checkpoint_bytes, asked[0], piece.points.shape[0]]), axis=0)
    return {"piece_bytes": worst[0], "checkpoint_bytes": worst[1], "asked": worst[2], "piece_points": worst[3],
            "n_dofs": np.array(model.layout.n)}


def main() -> None:
    task, case_file, out_file = sys.argv[1:4]
    comm = MPI.COMM_WORLD
    data = json.loads(open(case_file).read())
    u = np.array(data.pop("u")) if "u" in data else None
    if task == "history_auto_amg":
        import rockfrac.parallel.solvers as solvers

        solvers.AMG_FROM_3D = 0
    if task == "history_short_room":
        import rockfrac.solve.petsc as petsc

        petsc.MUMPS_SADDLE_WORKSPACE = 20
    if task == "histories":
        result = histories(data["cases"], comm, case_file)
    else:
        try:
            built = build_distributed(parse_case(data, case_file), comm, case_file)
            if task == "traffic":
                result = traffic(built, comm)
            elif task == "elimination":
                result = elimination(built, comm)
            else:
                result = history(built, comm) if task.startswith("history") else system(built, comm, u)
        except CaseError as err:
            result = {"error": np.array(str(err))}
    result["ranks"] = np.array(comm.Get_size())
    if comm.rank == 0:
        np.savez(out_file, **result)


if __name__ == "__main__":
    main()
