"""Linear solvers of a distributed model, through PETSc's options: MUMPS's parallel LU by default,
GMRES with GAMG (the rigid-body modes of the owned nodes as its near-null space) or hypre's
BoomerAMG for large systems, preconditioned on the right (the tolerance is on the true residual).
The options each one sets are in its ``options`` (the run names the solver)."""

from __future__ import annotations

import numpy as np

from rockfrac.parallel.layout import Layout, petsc
from rockfrac.parallel.model import DistributedMatrix
from rockfrac.solve.fallback import Handover
from rockfrac.solve.linear import AMG_FROM_3D
from rockfrac.solve.petsc import KspFactor, MumpsRoom, run_ksp, saddle_options, set_room, split_fields


class _Factor(KspFactor):
    """A configured KSP on one distributed matrix: ``solve(b)`` as often as needed (destroyed when
    dropped, :class:`rockfrac.solve.petsc.KspFactor`)."""

    def __init__(self, ksp, layout: Layout, *owned):
        super().__init__(ksp, *owned)
        self._layout = layout

    def solve(self, b: np.ndarray) -> np.ndarray:
        """x with A x = b (b read on the owned dofs), on the local dofs (owned and ghosts)."""
        rhs = self._layout.to_vec(b)
        x = rhs.duplicate()
        try:
            self.iterations = run_ksp(self._ksp, rhs, x)
            return self._layout.from_vec(x)
        finally:
            rhs.destroy()
            x.destroy()


class DistributedSolver(MumpsRoom):
    """A KSP configured by PETSc options on the distributed tangent."""

    name = ""
    options: dict[str, str] = {}
    rigid_modes = False  # give the preconditioner the rigid-body modes as its near-null space
    krylov = False  # an iterative solver: a Schur field split where there are multipliers

    def begin_step(self) -> None:
        return None

    def factorize(self, a: DistributedMatrix) -> _Factor:
        layout = a.layout
        saddle = self.krylov and layout.has_multipliers
        modes = layout.rigid_modes() if self.rigid_modes else None
        if modes is not None and not saddle:
            a.mat.setNearNullSpace(modes)
        options = saddle_options(self.options) if saddle else dict(self.options)

        def make(room: int | None) -> _Factor:
            self._release_last()
            ksp = petsc().KSP().create(comm=layout.comm)
            ksp.setOperators(a.mat)
            prefix = f"rockfrac_{self.name.replace('-', '_')}_"
            ksp.setOptionsPrefix(prefix)
            opts = petsc().Options()
            for k, v in options.items():
                opts[prefix + k] = v
            set_room(opts, prefix, room)
            owned: tuple = ()
            if saddle:
                ksp.getPC().setType("fieldsplit")
                owned = layout.fields()
                split_fields(ksp, owned[0], owned[1], modes)
            ksp.setFromOptions()
            return self._ready(_Factor(ksp, layout, *owned), f"PETSc {self.name} set-up")

        # MUMPS's LU of the whole saddle point: room for pivots off its zero diagonal
        lu = options.get("pc_factor_mat_solver_type") == "mumps"
        return self._with_room(make, saddle=layout.has_multipliers and lu)

    def solve(self, a: DistributedMatrix, b: np.ndarray) -> np.ndarray:
        return self.factorize(a).solve(b)


class MumpsLU(DistributedSolver):
    """MUMPS's parallel LU (the default)."""

    name = "petsc"
    options = {"ksp_type": "preonly", "pc_type": "lu", "pc_factor_mat_solver_type": "mumps"}


class KrylovGAMG(DistributedSolver):
    """GMRES(60) with PETSc's smoothed-aggregation AMG, the rigid-body modes as near-null space."""

    name = "petsc-gamg"
    rigid_modes = True
    krylov = True
    options = {"ksp_type": "gmres", "ksp_gmres_restart": "60", "ksp_rtol": "1e-11", "ksp_atol": "0",
               "ksp_max_it": "600", "ksp_pc_side": "right", "pc_type": "gamg"}


class KrylovHypre(DistributedSolver):
    """GMRES(60) with hypre's BoomerAMG."""

    name = "petsc-hypre"
    krylov = True
    options = {"ksp_type": "gmres", "ksp_gmres_restart": "60", "ksp_rtol": "1e-11", "ksp_atol": "0",
               "ksp_max_it": "600", "ksp_pc_side": "right", "pc_type": "hypre",
               "pc_hypre_type": "boomeramg"}


DISTRIBUTED_SOLVERS = {s.name: s for s in (MumpsLU, KrylovGAMG, KrylovHypre)}


def distributed_solver(name: str, n_dofs: int = 0, dim: int = 2, enrichment: bool = False
                       ) -> DistributedSolver | Handover:
    """The distributed solver for a [solver] linear name: 'petsc' is MUMPS's LU; 'auto' is too, except
    on a 3D model of at least AMG_FROM_3D dofs (RP multipliers included) without nodal cracks'
    enrichment, where it is GMRES + GAMG handing over to MUMPS's LU at its first failure (the serial
    rule, rockfrac.solve.linear)."""
    if name == "auto":
        if dim == 3 and n_dofs >= AMG_FROM_3D and not enrichment:
            return Handover(KrylovGAMG(), MumpsLU())
        return MumpsLU()
    if name not in DISTRIBUTED_SOLVERS:
        raise ValueError(f"[solver] linear = {name!r} is a serial solver; on several MPI ranks: "
                         f"{', '.join(['auto'] + sorted(DISTRIBUTED_SOLVERS))}")
    return DISTRIBUTED_SOLVERS[name]()
