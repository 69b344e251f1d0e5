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
from typing import TypeVar

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


# MUMPS's ICNTL(14), its workspace beyond the analysis's estimate [%] where the matrix is a saddle point
# (RP multipliers: zero diagonal entries, pivots delayed off the diagonal). MUMPS's default (20) ran out
# (INFO(1) = -9, reported as a singular tangent) on RP surfaces on every edge of the 4 x 6 specimen,
# where 100 ran them, and 100 ran out on the turned inclusion's annulus (tests/test_smoothed_normals.py)
# on 2 ranks, where 400 ran it.
MUMPS_SADDLE_WORKSPACE = "400"


class PetscDirect(_PetscBackend):
    """LU by MUMPS inside PETSc (one process)."""

    name = "petsc"
    dense_up_to = DENSE_UP_TO
    options = {"ksp_type": "preonly", "pc_type": "lu", "pc_factor_mat_solver_type": "mumps"}

    def _factorize(self, a: sp.csr_matrix) -> Factorization:
        self._release_last()
        m = self._matrix(a)
        ksp, opts, prefix = self._ksp(m)
        if not np.all(a.diagonal()):  # a saddle point: pivots off the diagonal
            opts[prefix + "mat_mumps_icntl_14"] = MUMPS_SADDLE_WORKSPACE
        ksp.setFromOptions()
        return self._ready(_PetscFactor(ksp, m), "PETSc LU (MUMPS)")


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
