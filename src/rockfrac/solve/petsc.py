"""PETSc linear solvers through petsc4py, on one process: the first step towards MPI runs (issue 17).

- ``petsc``: a direct LU of PETSc's AIJ matrix by MUMPS (``-pc_factor_mat_solver_type mumps``);
- ``petsc-gamg``: GMRES(60) preconditioned by PETSc's smoothed-aggregation AMG (GAMG), with the
  rigid-body modes as near-null space (3 in 2D, 6 in 3D), relative residual 1e-11;
- ``petsc-hypre``: GMRES(60) preconditioned by hypre's BoomerAMG (classical AMG, on the 3 x 3
  nodal blocks in 3D), relative residual 1e-11.

Both Krylov solvers precondition on the right, so that their tolerance is on the true residual
(a singular preconditioner cannot make a left-preconditioned residual small on a system without
a solution).

With multiplier rows (the RP CSE's saddle points, numbered after the displacements) the Krylov
solvers precondition by PETSc's Schur field split: ``upper`` factorization, the AMG on the
displacement block, MUMPS's LU on the multipliers' ``selfp`` Schur approximation C - B2 diag(A)^-1
B1 (the serial ``gmres-amg``'s preconditioner, :mod:`rockfrac.solve.saddle`, in PETSc's terms).

The same names run on several MPI ranks (:mod:`rockfrac.parallel.solvers`).

petsc4py is not a dependency of the serial install: Debian's ``python3-petsc4py-real`` (PETSc 3.18
with MUMPS, hypre, SuperLU_dist) is seen from a venv made by Debian's Python with
``--system-site-packages`` and NumPy < 2 (``make test`` builds one, ``.venv-mpi``); elsewhere these
backends are simply not installed (``available()``). The options each backend sets are in its
``options`` (the run's log names the backend).
"""

from __future__ import annotations

import weakref
from typing import Callable, TypeVar

import numpy as np
import scipy.sparse as sp

from rockfrac.solve.backend import DENSE_UP_TO, Factorization, SolverFailed, _Backend


def _petsc():
    from petsc4py import PETSc  # ImportError where petsc4py is not installed: not available

    return PETSc


def run_ksp(ksp, rhs, x) -> int:
    """Solve into x with a configured KSP; its iterations. SolverFailed if PETSc fails or the KSP
    does not converge (its reason named)."""
    petsc = _petsc()
    try:
        ksp.solve(rhs, x)
    except petsc.Error as err:
        raise SolverFailed(f"PETSc KSP failed: {err}") from None
    reason, iterations = ksp.getConvergedReason(), ksp.getIterationNumber()
    if reason < 0:
        raise SolverFailed(f"PETSc KSP did not converge (reason {reason}, {iterations} iterations)")
    return iterations


SADDLE_OPTIONS = {"pc_type": "fieldsplit", "pc_fieldsplit_type": "schur", "pc_fieldsplit_schur_fact_type": "upper",
                  "pc_fieldsplit_schur_precondition": "selfp", "fieldsplit_u_ksp_type": "preonly",
                  "fieldsplit_lambda_ksp_type": "preonly", "fieldsplit_lambda_pc_type": "lu",
                  "fieldsplit_lambda_pc_factor_mat_solver_type": "mumps"}


def saddle_options(options: dict[str, str]) -> dict[str, str]:
    """A Krylov solver's options with its preconditioner moved onto the displacement split of a
    Schur field split (the multipliers' block by LU)."""
    out = {k: v for k, v in options.items() if not k.startswith("pc_")}
    out.update(SADDLE_OPTIONS)
    out.update({"fieldsplit_u_" + k: v for k, v in options.items() if k.startswith("pc_")})
    return out


def split_fields(ksp, displacement, multipliers, modes=None) -> None:
    """Give the KSP's field split its two index sets (PETSc rows this process owns: displacements,
    multipliers), the displacement split the near-null space ``modes`` (or None)."""
    if modes is not None:
        displacement.compose("nearnullspace", modes)
    ksp.getPC().setFieldSplitIS(("u", displacement), ("lambda", multipliers))


class KspFactor:
    """A configured KSP (and the PETSc objects it alone uses), destroyed when the factor is dropped:
    petsc4py does not free them (0.12 GB a factorization at 1e5 dofs, measured), and Newton drops
    each factor before it assembles the next tangent. On several ranks the destruction is
    collective: every rank drops its factor at the same point of the same iteration."""

    def __init__(self, ksp, *owned):
        self._ksp, self._owned = ksp, owned
        self.iterations = 0

    def release(self) -> None:
        """Destroy the KSP, its factors or AMG hierarchy and Krylov vectors, now."""
        if self._ksp is not None:
            self._ksp.destroy()
            for obj in self._owned:
                obj.destroy()
            self._ksp, self._owned = None, ()

    def __del__(self) -> None:
        if self._ksp is not None and not _petsc().Sys.isFinalized():  # not at the interpreter's exit
            self.release()


F = TypeVar("F", bound=KspFactor)


class OneFactorAlive:
    """A solver that releases its last factor, should anything still hold it (a failed iteration's
    frame), before it makes the next: one KSP alive at a time."""

    _last: weakref.ref[KspFactor] | None = None

    def _release_last(self) -> None:
        last = self._last() if self._last is not None else None
        if last is not None:
            last.release()

    def _ready(self, factor: F, what: str) -> F:
        """Set the factor's KSP up and keep it as the last one; SolverFailed naming ``what`` (its KSP
        freed) where PETSc fails."""
        try:
            factor._ksp.setUp()
        except _petsc().Error as err:
            factor.release()
            raise SolverFailed(f"{what} failed: {err}") from None
        self._last = weakref.ref(factor)
        return factor


class _PetscFactor(KspFactor):
    """A configured KSP on one matrix: ``solve(b)`` as often as needed."""

    def solve(self, b: np.ndarray) -> np.ndarray:
        petsc = _petsc()
        rhs = petsc.Vec().createWithArray(np.ascontiguousarray(b, dtype=np.float64), comm=petsc.COMM_SELF)
        x = rhs.duplicate()
        try:
            self.iterations = run_ksp(self._ksp, rhs, x)
            out = x.getArray().copy()
        finally:
            rhs.destroy()
            x.destroy()
        if not np.all(np.isfinite(out)):
            raise SolverFailed(f"PETSc KSP gave a non-finite solution ({self.iterations} iterations)")
        return out


class _PetscBackend(OneFactorAlive, _Backend):
    options: dict[str, str] = {}

    def __init__(self, coordinates: np.ndarray | None = None) -> None:
        _petsc()
        self._coordinates = coordinates

    def _matrix(self, a: sp.csr_matrix):
        petsc = _petsc()
        a = sp.csr_matrix(a)
        a.sort_indices()
        m = petsc.Mat().createAIJ(a.shape, csr=(a.indptr.astype(petsc.IntType), a.indices.astype(petsc.IntType),
                                                a.data), comm=petsc.COMM_SELF)
        m.assemble()
        return m

    def _ksp(self, m):
        petsc = _petsc()
        ksp = petsc.KSP().create(comm=petsc.COMM_SELF)
        ksp.setOperators(m)
        prefix = f"rockfrac_{id(self)}_"
        ksp.setOptionsPrefix(prefix)
        opts = petsc.Options()
        for k, v in self.options.items():
            opts[prefix + k] = v
        return ksp, opts, prefix


# MUMPS's ICNTL(14), its workspace beyond the analysis's estimate [%], to start from where the matrix is a
# saddle point (RP multipliers: zero diagonal entries, pivots delayed off the diagonal). MUMPS's default
# (20) ran out (INFO(1) = -9) on RP surfaces on every edge of the 4 x 6 specimen, where 100 ran them,
# and 100 ran out on the turned inclusion's annulus (tests/test_smoothed_normals.py) on 2 ranks, where
# 400 ran it. Where it still runs out, the LU is made again with twice the room (MumpsRoom).
MUMPS_SADDLE_WORKSPACE = 400
# MUMPS's INFOG(1) codes whose cure is a larger ICNTL(14) (its users' guide, "Error diagnostics"):
# integer or real workspace too small for the factorization (-8, -9), the solution (-11, -14), the
# iterative refinement (-12, -15), or a send or reception buffer too small (-17, -20)
MUMPS_OUT_OF_WORKSPACE = (-8, -9, -11, -12, -14, -15, -17, -20)
MUMPS_MAX_WORKSPACE = 12800  # the most room given [%] before the factorization counts as failed


def mumps_shortfall(ksp) -> tuple[int, int] | None:
    """(INFOG(1), ICNTL(14)) where a set-up KSP's LU by MUMPS ran out of workspace; None where it did
    not or the KSP is no MUMPS LU. INFOG is global: every rank gets the same answer."""
    pc = ksp.getPC()
    if pc.getType() != "lu" or pc.getFactorSolverType() != "mumps":
        return None
    factor = pc.getFactorMatrix()
    info = factor.getMumpsInfog(1)
    return (info, factor.getMumpsIcntl(14)) if info in MUMPS_OUT_OF_WORKSPACE else None


def set_room(opts, prefix: str, room: int | None) -> None:
    """MUMPS's ICNTL(14) in PETSc's options for the KSP of ``prefix``: ``room`` [%], or MUMPS's default
    (an earlier value under the same prefix taken out of the options, which outlive the KSPs)."""
    if room is None:
        opts.delValue(prefix + "mat_mumps_icntl_14")
    else:
        opts[prefix + "mat_mumps_icntl_14"] = str(room)


class MumpsRoom(OneFactorAlive):
    """An LU by MUMPS made again, with twice its workspace (ICNTL(14)), where MUMPS runs out of it,
    up to MUMPS_MAX_WORKSPACE; the room that worked is kept for the next factorizations and the run's
    log says how it grew. (PETSc reports a factorization out of workspace as a failed preconditioner,
    and Newton as a singular tangent.)"""

    workspace: int | None = None  # ICNTL(14) [%] of the last factorization; None: MUMPS's default
    _grown: tuple[str, ...] = ()  # each time the room grew, for the run's log

    def _with_room(self, make: Callable[[int | None], F], saddle: bool) -> F:
        """make(ICNTL(14) or None) until its factor is not short of workspace."""
        room = self.workspace
        if saddle:
            room = max(room or 0, MUMPS_SADDLE_WORKSPACE)
        while True:
            factor = make(room)
            short = mumps_shortfall(factor._ksp)
            if short is None:
                self.workspace = room
                return factor
            info, had = short
            factor.release()
            if 2 * had > MUMPS_MAX_WORKSPACE:
                raise SolverFailed(f"MUMPS's LU ran out of workspace (INFOG(1) = {info}) with ICNTL(14) = "
                                   f"{had} %, the most rockfrac gives it is {MUMPS_MAX_WORKSPACE} %")
            room = 2 * had
            self._grown += (f"MUMPS ran out of workspace (INFOG(1) = {info}) with ICNTL(14) = {had} %: "
                            f"factorized again with {room} %",)

    def notes(self) -> list[str]:
        """What the run's log says: each time the room grew."""
        return list(self._grown)


class PetscDirect(MumpsRoom, _PetscBackend):
    """LU by MUMPS inside PETSc (one process)."""

    name = "petsc"
    dense_up_to = DENSE_UP_TO
    options = {"ksp_type": "preonly", "pc_type": "lu", "pc_factor_mat_solver_type": "mumps"}

    def _factorize(self, a: sp.csr_matrix) -> Factorization:
        def make(room: int | None) -> _PetscFactor:
            self._release_last()
            m = self._matrix(a)
            ksp, opts, prefix = self._ksp(m)
            set_room(opts, prefix, room)
            ksp.setFromOptions()
            return self._ready(_PetscFactor(ksp, m), "PETSc LU (MUMPS)")

        return self._with_room(make, saddle=not np.all(a.diagonal()))  # zero diagonals: pivots off it


class PetscGAMG(_PetscBackend):
    """GMRES(60) + GAMG inside PETSc (one process); the rigid-body modes as near-null space."""

    name = "petsc-gamg"
    options = {"ksp_type": "gmres", "ksp_gmres_restart": "60", "ksp_rtol": "1e-11", "ksp_atol": "0",
               "ksp_max_it": "600", "ksp_pc_side": "right", "pc_type": "gamg"}

    def _factorize(self, a: sp.csr_matrix) -> Factorization:
        self._release_last()
        petsc = _petsc()
        m = self._matrix(a)
        x = self._coordinates
        owned: list = [m]
        if x is None or a.shape[0] < x.size:  # no nodes to build the rigid-body modes from
            ksp, _, _ = self._ksp(m)
            ksp.setFromOptions()
            return self._ready(_PetscFactor(ksp, *owned), "PETSc GAMG set-up")
        dim, n_u = x.shape[1], x.size
        coords = petsc.Vec().createWithArray(np.ascontiguousarray(x.ravel()), bsize=dim, comm=petsc.COMM_SELF)
        modes = petsc.NullSpace().createRigidBody(coords)  # 3 in 2D, 6 in 3D, orthonormal
        coords.destroy()
        ksp, opts, prefix = self._ksp(m)
        if a.shape[0] > n_u:  # multipliers after the displacements: the Schur field split
            for k, v in saddle_options(self.options).items():
                opts[prefix + k] = v
            ksp.getPC().setType("fieldsplit")
            u = petsc.IS().createStride(n_u, 0, 1, comm=petsc.COMM_SELF)
            u.setBlockSize(dim)
            lam = petsc.IS().createStride(a.shape[0] - n_u, n_u, 1, comm=petsc.COMM_SELF)
            split_fields(ksp, u, lam, modes)
            owned += [u, lam]
        else:
            m.setBlockSize(dim)
            m.setNearNullSpace(modes)  # the matrix keeps its reference
        modes.destroy()  # whoever uses them holds a reference
        ksp.setFromOptions()
        return self._ready(_PetscFactor(ksp, *owned), "PETSc GAMG set-up")


class PetscHypre(PetscGAMG):
    """GMRES(60) + hypre's BoomerAMG inside PETSc (one process)."""

    name = "petsc-hypre"
    options = {"ksp_type": "gmres", "ksp_gmres_restart": "60", "ksp_rtol": "1e-11", "ksp_atol": "0",
               "ksp_max_it": "600", "ksp_pc_side": "right", "pc_type": "hypre",
               "pc_hypre_type": "boomeramg"}
