"""Linear solver backends sharing one verb: ``solve(A, b) -> x`` for CSR matrices.

``factorize(A)`` returns an object whose ``solve(b)`` reuses the factorization (path following
needs two right-hand sides per iteration). A backend that cannot solve raises ``SolverFailed``, a
``RuntimeError``: the Newton loop turns it into a failed iteration, and the stepping cuts back.

Backends, fastest first on this project's tangents (benchmarks/README.md, "Linear solvers"):
PARDISO (MKL, pypardiso), MUMPS (python-mumps, needs Debian's libmumps), SciPy's SuperLU, and
GMRES preconditioned by smoothed-aggregation AMG (pyamg). The optional ones are used when they
import; ``auto`` picks the first installed of ``PREFERENCE`` (GMRES + AMG for a large 3D model:
``make_solver``). The contract and SuperLU live in :mod:`rockfrac.solve.backend`, the iterative
backend in :mod:`rockfrac.solve.iterative`; both are re-exported here.
"""

from __future__ import annotations

import glob
import os
import sys
from typing import Any

import numpy as np
import scipy.sparse as sp

from rockfrac.solve.backend import (  # noqa: F401 (the contract and SuperLU, re-exported)
    DENSE_UP_TO,
    Factorization,
    LinearSolver,
    SolverFailed,
    SuperLU,
    _Backend,
    _DenseLU,
    is_symmetric,
)
from rockfrac.solve.fallback import Checked, Handover  # noqa: F401 (re-exported)
from rockfrac.solve.iterative import KrylovAMG, rigid_modes_3d  # noqa: F401 (re-exported)
from rockfrac.solve.petsc import PetscDirect, PetscGAMG, PetscHypre


class _Pattern:
    """A CSR sparsity pattern remembered by identity of its arrays, and by a digest of their values
    as a fallback (no copy: at 2e6 dofs the index arrays are 150 MB)."""

    def __init__(self, a: sp.csr_matrix):
        self.indptr, self.indices = a.indptr, a.indices
        self._digest = self._of(a)

    @staticmethod
    def _of(a: sp.csr_matrix) -> tuple:
        import hashlib

        h = hashlib.blake2b(digest_size=16)
        for arr in (a.indptr, a.indices):  # hashed in place (buffer protocol), dtype included
            h.update(str(arr.dtype).encode())
            h.update(np.ascontiguousarray(arr).data.cast("B"))
        return a.shape, a.nnz, h.digest()

    def same(self, a: sp.csr_matrix) -> bool:
        if a.indptr is self.indptr and a.indices is self.indices:
            return True
        same = self._of(a) == self._digest
        if same:  # the next matrix built on the same arrays is recognized by identity
            self.indptr, self.indices = a.indptr, a.indices
        return same


def _find_mkl_runtime() -> None:
    """Point pypardiso at MKL's runtime in this environment's library folder (``PYPARDISO_MKL_RT``).

    Without it every ``PyPardisoSolver()`` runs ``ctypes.util.find_library`` (ldconfig, gcc and ld
    as subprocesses; it fails for the PyPI ``mkl`` wheel) and then globs the whole environment:
    0.11 s per solver here, paid by every ``rockfrac run``. A path the user set is kept; where no
    runtime is found directly, pypardiso searches as before.
    """
    _choose_mkl_threading()
    _choose_mkl_reproducibility()
    if os.environ.get("PYPARDISO_MKL_RT"):
        return
    for folder in ("lib", os.path.join("Library", "bin")):
        found = sorted(glob.glob(os.path.join(sys.prefix, folder, "*mkl_rt*")), key=len)
        if found:
            os.environ["PYPARDISO_MKL_RT"] = found[0]
            return


def _choose_mkl_reproducibility() -> None:
    """Run MKL in its conditional numerical reproducibility mode (``MKL_CBWR=AUTO``, before MKL
    loads), unless the user chose a mode.

    PARDISO on its OpenMP threads (systems of ``Pardiso.serial_below`` rows and more) otherwise
    factorizes the same matrix to different last bits from one call to the next, as the threads'
    partial sums meet in a different order. On an ill-conditioned saddle point (RP surfaces on every
    edge of the 0.9 mm disc: 40976 rows, augmentation 1e15 Pa/m) the solutions of repeated
    factorizations differed by 2e-6 relative in four processes out of five, and a run that decides
    active sets from them took another path (250 against 448 steps, benchmarks/README.md,
    "Fragmentation"). In the CNR mode every call gives the same bits; one-thread solves (smaller
    systems, the paper's study) are unchanged.
    """
    if not os.environ.get("MKL_CBWR"):
        os.environ["MKL_CBWR"] = "AUTO"


def _choose_mkl_threading() -> None:
    """Run MKL on GNU OpenMP (``MKL_THREADING_LAYER=GNU``, before MKL loads) where libgomp is
    present, unless the user chose a layer.

    MKL's single runtime picks its threading layer when it loads: GNU OpenMP if libgomp is already
    in the process (Numba's parallel kernels load it when they first run), Intel's otherwise. The
    two give PARDISO factors that differ in the last bits, so a run's numbers depended on whether a
    parallel Numba kernel had run before the first solve: a run resumed from a checkpoint, or run
    after another in the same process, differed from a fresh one at round-off. One fixed choice
    makes them equal; GNU also keeps one OpenMP runtime in the process instead of two.
    """
    if os.environ.get("MKL_THREADING_LAYER"):
        return
    import ctypes

    try:
        ctypes.CDLL("libgomp.so.1")
    except OSError:  # no GNU OpenMP here: MKL's default (Intel OpenMP)
        return
    os.environ["MKL_THREADING_LAYER"] = "GNU"


class _PardisoFactor:
    def __init__(self, owner: Pardiso, values: np.ndarray, generation: int):
        self._owner, self._values, self._generation = owner, values, generation

    def solve(self, b: np.ndarray) -> np.ndarray:
        if self._generation != self._owner.generation:
            raise SolverFailed("PARDISO factorization used after a newer one replaced it")
        return self._owner.substitute(self._values, b)


class Pardiso(_Backend):
    """Intel MKL PARDISO through pypardiso (optional: the ``fast`` extra).

    Unsymmetric (mtype 11), or symmetric indefinite (mtype -2, Bunch-Kaufman pivoting, on the upper
    triangle) where the matrix is symmetric: with ``symmetric = "auto"`` every matrix of at least
    ``symmetric_from`` rows is checked (max |A - A^T| <= ``symmetry_tol`` max |A|, through the
    transposition map of its pattern, made once per pattern), and the analysis is redone when the
    type changes (an elastic step, then a plastic one). Symmetric mode halves the factors' memory and
    time (benchmarks/README.md, "Problem A"); small systems skip the check (not worth it there, and
    their factors stay those of the unsymmetric path). ``symmetric = "unsymmetric"`` never checks.

    The sparsity pattern of a run's tangents never changes (Dirichlet rows are zeroed in place), so
    the analysis (fill-reducing ordering and symbolic factorization, phase 11) is kept; each
    factorization is a numerical one (phase 22) after the previous factors are freed (phase 0:
    memory stays flat), and each solve a forward/backward substitution (phase 33). A matrix with
    another pattern releases everything (phase -1) and is analysed afresh. So is the first matrix
    of every load step (``begin_step``, called by the Newton loop): MKL's matching and scaling are
    computed from the analysed matrix's values, so the factors depend on the matrix analysed, and
    a run resumed from a checkpoint (at a step's start) must analyse where the uninterrupted run
    did to stay bit for bit the same; it also keeps the matching fit for the step's tangents.

    Systems of fewer than ``serial_below`` rows run every phase on one thread, through MKL's
    thread-local setting (``mkl_set_num_threads_local``, restored after each call; the process-wide
    MKL setting and other threads are untouched). MKL's OpenMP threads pay off only on an idle
    machine: at 1e4 dofs 1.3-1.5x faster than one thread in the Newton loop, while one other busy
    process on these 2-core machines made them 6x slower (and 15x at 1e3 dofs); from 5e4 dofs
    they were even under that load. A system keeps one thread count through all its phases (the
    count depends on its size only). Where the MKL runtime lacks the symbol, MKL's default is used
    (benchmarks/README.md, "Serial path for small systems").

    ``matching = False``: an unsymmetric matrix is factorized without MKL's default weighted matching
    and scaling (iparm(11) = iparm(13) = 0, every other control MKL's default). On the grains' RP
    saddle points with loops of multipliers round every node the matching perturbed 650-880 pivots
    (residuals up to 11) and cost 2.4x the refactorization; without it 60-430 pivots, every residual
    within 1e-6 (benchmarks/README.md, "PARDISO without matching"). On the paper's rigid RP
    saddle point the matching is the better: no pivot perturbed. Without the matching the analysis
    reads the pattern only, so it is kept from one load step to the next (``begin_step``).

    ``multipliers_from = n_u`` (without matching only): a matrix with more than n_u rows is a saddle
    point, displacements first, and is analysed in the elimination order of
    :func:`rockfrac.solve.ordering.saddle_order` (iparm(5) = 1, a user permutation) instead of
    PARDISO's METIS: each multiplier after its displacements, so its pivot is not zero.
    """

    name = "pardiso"
    dense_up_to = DENSE_UP_TO
    serial_below = 30_000  # rows below which PARDISO runs on one thread (see the class note)
    symmetric = "auto"  # "auto": mtype -2 where the matrix is symmetric (checked); "unsymmetric": always 11
    symmetric_from = 5_000  # rows from which "auto" checks the symmetry
    symmetry_tol = 1e-13  # max |A - A^T| / max |A| accepted as symmetric (assembly round-off)

    def __init__(self, matching: bool = True, multipliers_from: int | None = None) -> None:
        import pypardiso  # noqa: F401  (fails here, not mid-run, if it is missing)

        if multipliers_from is not None and matching:
            raise ValueError("Pardiso: a saddle-point ordering (multipliers_from) needs matching=False")
        self.matching = matching
        self.multipliers_from = multipliers_from
        if not matching:
            self.name = "pardiso without matching" + (", saddle ordering" if multipliers_from is not None else "")

        self._solver: Any = None  # pypardiso's solver (its ctypes handle and arrays)
        self._pattern: _Pattern | None = None
        self.mtype = 11  # PARDISO's matrix type of the analysed pattern: 11, or -2 (symmetric indefinite)
        self._upper: np.ndarray | None = None  # data positions of the upper triangle (mtype -2)
        self._ia: Any = None  # 1-based int32 index arrays of the analysed pattern
        self._ja: Any = None
        self._factored = False
        self._new_step = False
        self.generation = 0  # factorizations done; a factor object is valid for its own only
        self.analyses = 0  # symbolic analyses done (phase 11)
        self._rows = 0  # rows of the analysed pattern
        self._set_threads_local = None  # MKL's mkl_set_num_threads_local, once the runtime is loaded
        self.threads_used: int | None = None  # MKL thread-local setting of the last call (0: MKL's default)

    @staticmethod
    def _threads_function(libmkl):
        """MKL's ``mkl_set_num_threads_local`` from the loaded runtime, or None where it is missing.

        The C function (by value) is exported as ``MKL_Set_Num_Threads_Local``: mkl_service.h maps
        the lower-case name to it, and the lower-case symbol in mkl_rt is the Fortran interface,
        which takes a pointer (called with a plain int it crashes).
        """
        import ctypes

        try:
            f = libmkl.MKL_Set_Num_Threads_Local
        except AttributeError:  # an MKL without it: stay with MKL's default threads
            return None
        f.argtypes = [ctypes.c_int]
        f.restype = ctypes.c_int
        return f

    def _call(self, phase: int, values: np.ndarray | None, b: np.ndarray) -> np.ndarray:
        """One PARDISO call on the analysed pattern with the matrix values PARDISO reads (the upper
        triangle's in symmetric mode; None: no matrix, for the release phases) and right-hand sides b."""
        import ctypes

        from pypardiso.pardiso_wrapper import PyPardisoError

        s = self._solver
        x = np.zeros_like(b)
        err = ctypes.c_int32(0)
        i32, f64 = ctypes.POINTER(ctypes.c_int32), ctypes.POINTER(ctypes.c_double)
        n = 0 if values is None else self._rows
        data = np.zeros(1) if values is None else values
        ia = np.zeros(1, np.int32) if values is None else self._ia
        ja = np.zeros(1, np.int32) if values is None else self._ja
        # a small system: one MKL thread for this call (thread-local; the previous setting restored)
        set_local = self._set_threads_local if self._rows < self.serial_below else None
        previous = set_local(1) if set_local is not None else None
        self.threads_used = 1 if set_local is not None else 0
        try:
            s._mkl_pardiso(s.pt.ctypes.data_as(ctypes.POINTER(s._pt_type[0])),
                           ctypes.byref(ctypes.c_int32(1)), ctypes.byref(ctypes.c_int32(1)),
                           ctypes.byref(ctypes.c_int32(self.mtype)), ctypes.byref(ctypes.c_int32(phase)),
                           ctypes.byref(ctypes.c_int32(n)), data.ctypes.data_as(f64),
                           ia.ctypes.data_as(i32), ja.ctypes.data_as(i32), s.perm.ctypes.data_as(i32),
                           ctypes.byref(ctypes.c_int32(1 if b.ndim == 1 else b.shape[1])),
                           s.iparm.ctypes.data_as(i32), ctypes.byref(ctypes.c_int32(0)),
                           b.ctypes.data_as(f64), x.ctypes.data_as(f64), ctypes.byref(err))
        finally:
            if previous is not None:
                set_local(previous)
        if err.value != 0:
            raise SolverFailed(str(PyPardisoError(err.value)))
        return x

    def _release(self, everything: bool) -> None:
        if self._solver is None or self._pattern is None:  # nothing analysed yet
            return
        self._call(-1 if everything else 0, None, np.zeros(0))
        self._factored = False
        if everything:
            self._solver.pt[:] = 0  # a released handle starts again as a fresh one
            self._pattern = None

    def analyse(self, a: sp.csr_matrix, mtype: int = 11) -> None:
        """Ordering and symbolic factorization of ``a``'s pattern (phase 11) as matrix type ``mtype``."""
        import pypardiso

        if self._solver is None:
            _find_mkl_runtime()
            self._solver = pypardiso.PyPardisoSolver(mtype=11)
            self._set_threads_local = self._threads_function(self._solver.libmkl)
        self._release(everything=True)  # with the type it was analysed as
        if not np.diff(a.indptr).all():
            raise SolverFailed("matrix has an empty row (singular)")
        self._pattern = _Pattern(a)
        self._rows = a.shape[0]
        self.mtype = mtype
        if mtype == 11:
            self._upper = None
            self._ia = (a.indptr + 1).astype(np.int32)
            self._ja = (a.indices + 1).astype(np.int32)
        else:  # the upper triangle, diagonal included (every row keeps its diagonal slot)
            rows = np.repeat(np.arange(a.shape[0]), np.diff(a.indptr))
            self._upper = np.flatnonzero(a.indices >= rows)
            self._ia = np.zeros(a.shape[0] + 1, dtype=np.int32)
            self._ia[1:] = np.cumsum(np.bincount(rows[self._upper], minlength=a.shape[0]))
            self._ia += 1
            self._ja = (a.indices[self._upper] + 1).astype(np.int32)
        self._set_controls()
        if self.multipliers_from is not None and 0 < self.multipliers_from < a.shape[0]:
            from rockfrac.solve.ordering import saddle_order

            # iparm(5) = 1: the user's permutation; perm(k) is the (1-based) row eliminated k-th
            self._solver.perm = (saddle_order(a, self.multipliers_from) + 1).astype(np.int32)
            self._solver.iparm[4] = 1
        self._call(11, a.data if mtype == 11 else a.data[self._upper], np.zeros((a.shape[0], 1)))
        self._new_step = False
        self.analyses += 1

    def _set_controls(self) -> None:
        """PARDISO's iparm for the analysed type: MKL's defaults (iparm(1) = 0: PARDISO sets them), or,
        without matching, the defaults MKL's ``pardisoinit`` gives the type with iparm(11) = iparm(13) = 0
        (no scaling, no weighted matching; the symmetric type has neither by default)."""
        if self.matching:  # untouched: MKL's defaults, as the first version ran them
            return
        import ctypes

        iparm = self._solver.iparm
        iparm[:] = 0
        scratch = np.zeros(64, dtype=np.int64)  # pardisoinit also clears a handle: not the live one
        self._solver.libmkl.pardisoinit(scratch.ctypes.data_as(ctypes.c_void_p),
                                        ctypes.byref(ctypes.c_int32(self.mtype)),
                                        iparm.ctypes.data_as(ctypes.POINTER(ctypes.c_int32)))
        iparm[10] = 0  # iparm(11): no scaling
        iparm[12] = 0  # iparm(13): no weighted matching

    def matrix_type(self, a: sp.csr_matrix) -> int:
        """11, or -2 where ``symmetric = "auto"``, ``a`` has at least ``symmetric_from`` rows and is
        symmetric to ``symmetry_tol`` (one compiled pass, stopping at the first asymmetric entry)."""
        if self.symmetric == "unsymmetric" or a.shape[0] < self.symmetric_from:
            return 11
        if self.symmetric != "auto":
            raise ValueError(f"Pardiso.symmetric = {self.symmetric!r}: 'auto' or 'unsymmetric'")
        return -2 if a.nnz and is_symmetric(a.indptr, a.indices, a.data, self.symmetry_tol) else 11

    def begin_step(self) -> None:
        """A load step starts: with MKL's matching its first factorization analyses afresh (see the
        class note); without it the analysis is symbolic only (its ordering, ours or METIS's, reads the
        pattern alone), its factors of a matrix are bit for bit those of a fresh analysis, and it is
        kept (on the grains' RP saddle points 0.45-0.5 s a step, 9 % of a run on the fallback)."""
        self._new_step = self.matching

    def _factorize(self, a: sp.csr_matrix) -> Factorization:
        a = sp.csr_matrix(a)
        if a.dtype != np.float64:
            a = a.astype(np.float64)
        if not a.has_sorted_indices:
            a = a.sorted_indices()
        mtype = self.matrix_type(a)
        if self._pattern is None or self._new_step or mtype != self.mtype or not self._pattern.same(a):
            self.analyse(a, mtype)
        elif self._factored:
            self._release(everything=False)  # the previous factors
        # the values PARDISO reads (the upper triangle in symmetric mode), kept: phase 33 refines
        # iteratively against the matrix, and the caller may reuse its array
        values = a.data.copy() if self.mtype == 11 else a.data[self._upper]
        self._call(22, values, np.zeros((a.shape[0], 1)))
        self._factored = True
        self.generation += 1
        return _PardisoFactor(self, values, self.generation)

    def substitute(self, values: np.ndarray, b: np.ndarray) -> np.ndarray:
        """Solve with the current factors (phase 33, with PARDISO's iterative refinement against the
        factorized matrix's ``values``)."""
        b = np.asfortranarray(b, dtype=np.float64)
        return np.ascontiguousarray(self._call(33, values, b))

    def __del__(self) -> None:
        if getattr(self, "_solver", None) is not None:
            try:
                self._release(everything=True)
            except Exception:  # noqa: BLE001 -- at interpreter shutdown numpy may already be gone
                pass


class _MumpsFactor:
    def __init__(self, ctx, generation: int, owner: Mumps):
        self._ctx, self._generation, self._owner = ctx, generation, owner

    def solve(self, b: np.ndarray) -> np.ndarray:
        if self._generation != self._owner.generation:
            raise SolverFailed("MUMPS factorization used after a newer one replaced it")
        try:
            return np.asarray(self._ctx.solve(b))
        except Exception as err:  # noqa: BLE001 -- MUMPS reports errors with its own exception type
            raise SolverFailed(f"MUMPS solve failed: {err}") from err


class Mumps(_Backend):
    """MUMPS (sequential) through python-mumps (optional: needs Debian's libmumps-seq-dev to build).

    The analysis is done once per sparsity pattern and reused by each numerical factorization.
    """

    name = "mumps"
    dense_up_to = DENSE_UP_TO

    def __init__(self) -> None:
        import mumps  # noqa: F401

        self._ctx: Any = None  # python-mumps's context
        self._pattern: _Pattern | None = None
        self.generation = 0
        self.analyses = 0

    def _factorize(self, a: sp.csr_matrix) -> Factorization:
        import mumps

        a = sp.csr_matrix(a)
        try:
            if self._pattern is None or not self._pattern.same(a):
                self._ctx = mumps.Context()
                self._ctx.set_matrix(a)
                self._ctx.analyze()
                self._pattern = _Pattern(a)
                self.analyses += 1
            else:
                self._ctx.set_matrix(a)  # same pattern: the analysis is kept
            self._ctx.factor(reuse_analysis=True)
        except Exception as err:  # noqa: BLE001
            raise SolverFailed(f"MUMPS factorization failed: {err}") from err
        self.generation += 1
        return _MumpsFactor(self._ctx, self.generation, self)


SOLVERS = {"pardiso": Pardiso, "mumps": Mumps, "superlu": SuperLU, "gmres-amg": KrylovAMG, "petsc": PetscDirect,
           "petsc-gamg": PetscGAMG, "petsc-hypre": PetscHypre}


def available() -> list[str]:
    """Names of the backends that can be used on this machine."""
    names = []
    for name, cls in SOLVERS.items():
        try:
            cls()
        except ImportError:
            continue
        names.append(name)
    return names


# fastest first, measured in benchmarks/README.md ("Linear solvers"): PARDISO on every system from
# 1e4 to 1e6 dofs; MUMPS before SuperLU on 5 of the 6 (not the 1e6-dof band); the iterative
# backend is chosen by 'auto' only for large 3D models (AMG_FROM_3D)
PREFERENCE = ("pardiso", "mumps", "superlu")


# 'auto' on a 3D model: GMRES + AMG from this many dofs, the direct backend below (benchmarks/README.md,
# "3D scaling": PARDISO's 3D fill grows faster than AMG's work; with RP joints, "3D joints to 1e6 dofs")
AMG_FROM_3D = 100_000


def make_solver(name: str, coordinates: np.ndarray | None = None, n_dofs: int = 0,
                enrichment: bool = False) -> LinearSolver:
    """Backend by name ('auto': the fastest installed); raises ValueError listing the available ones.
    coordinates: the mesh's nodes, which the iterative backend uses for its near-null space in 3D
    (and to tell RP multipliers, numbered after the displacements, from them).
    'auto' on a 3D model of at least AMG_FROM_3D dofs (RP multipliers or not) without nodal cracks'
    ``enrichment`` (their unknowns span the region that may crack: a Schur block as large as that
    is no preconditioner): GMRES + AMG, handing over to the direct backend at its first failure.
    PARDISO's solves are checked (``Checked``): under 'auto' PARDISO without matching (in the saddle
    order where the tangent has multipliers after the displacements) retries an inaccurate one, and
    SuperLU one that stays inaccurate; each takes over where it is accurate (three matrices); chosen
    by name, they are counted in the run's log."""
    if name == "auto":
        installed = available()
        first = next(n for n in PREFERENCE if n in installed)
        # multipliers (RP CSE) numbered after the displacements: a saddle point, ordered as one
        saddle = (coordinates.size if coordinates is not None and n_dofs > coordinates.size and not enrichment
                  else None)
        direct: LinearSolver = (Checked(Pardiso(), Checked(Pardiso(matching=False, multipliers_from=saddle),
                                                           SuperLU())) if first == "pardiso" else SOLVERS[first]())
        three_d = coordinates is not None and coordinates.shape[1] == 3
        if three_d and n_dofs >= AMG_FROM_3D and not enrichment and "gmres-amg" in installed:
            return Handover(KrylovAMG(coordinates), direct)
        return direct
    if name not in SOLVERS:
        raise ValueError(f"unknown linear solver {name!r}; known: {sorted(SOLVERS)}")
    try:
        if name == "gmres-amg":
            return KrylovAMG(coordinates)
        if name == "petsc":
            return PetscDirect(coordinates)
        if name == "petsc-gamg":
            return PetscGAMG(coordinates)
        if name == "petsc-hypre":
            return PetscHypre(coordinates)
        if name == "pardiso":
            return Checked(Pardiso(), None)
        return SOLVERS[name]()
    except ImportError as err:
        raise ValueError(f"linear solver {name!r} is not installed here ({err}); available: {available()}") from None
