"""[solver] and [output]: Newton, stepping and linear solver options; what a run writes."""

from __future__ import annotations

from enum import Enum
from typing import Literal

from pydantic import Field, model_validator

from rockfrac.values import Count
from rockfrac.values import Section as _Section


class LinearSolverName(str, Enum):
    auto = "auto"
    superlu = "superlu"
    pardiso = "pardiso"
    mumps = "mumps"
    gmres_amg = "gmres-amg"
    petsc = "petsc"
    petsc_gamg = "petsc-gamg"
    petsc_hypre = "petsc-hypre"


class SolverSection(_Section):
    linear: LinearSolverName = Field(LinearSolverName.auto, strict=False,
                                     description="'auto' (the fastest installed: pardiso, mumps, superlu), "
                                     "'superlu' (SciPy), 'pardiso' (needs pypardiso), 'mumps' (needs "
                                     "python-mumps), 'gmres-amg' (iterative, needs pyamg), or with petsc4py 'petsc' (MUMPS's LU), "
                                     "'petsc-gamg' or 'petsc-hypre' (GMRES + AMG); on several MPI ranks 'auto' is "
                                     "'petsc', or 'petsc-gamg' handing over to it on a 3D model of 1e5 dofs or more")

    @model_validator(mode="after")
    def _solver_installed(self) -> SolverSection:
        from rockfrac.solve.linear import available

        if self.linear.value != "auto" and self.linear.value not in available():
            raise ValueError(f"linear = {self.linear.value!r} is not installed here; available: {available()}")
        return self
    max_iterations: int = Field(25, ge=1, le=1000, description="most Newton iterations of a step")
    tol_residual: float = Field(1e-8, ge=1e-14, le=1e-2, description="relative residual norm to converge")
    tol_energy: float = Field(1e-10, ge=1e-20, le=1e-2, description="relative energy norm to converge")
    cutback: float = Field(0.5, ge=0.01, le=0.9, description="factor on the step after a failed one")
    min_step: float = Field(1e-4, ge=1e-12, le=1, description="smallest increment, fraction of the nominal")
    grow: float = Field(1.5, ge=1.0, le=10.0, description="factor on the step after an easy one (up to the nominal; "
                        "1: a cut-back step stays short)")
    easy_iterations: int = Field(6, ge=0, le=1000, description="a converged step is easy (the next may grow) if "
                                 "it took at most this many Newton iterations without an active-set change "
                                 "(max_iterations or more: every converged step)")
    locate_activation: bool = Field(True, description="end a step where a cohesive surface first yields "
                                    "(its peak becomes a step; a path step that yields is done again as a load "
                                    "step to it); false steps over it, as the paper's study does")
    implex_tol: float = Field(0.05, ge=1e-6, le=10.0, description="IMPL-EX: largest |T_ex - T| of a step "
                              "relative to the law's strength; a step above it is shortened, below it may grow")
    # unset (None) when not given, so that a case without it resolves to the text it had before the key
    # existed: a checkpoint's case digest is that text's, and the runs checkpointed then still resume
    elimination: bool | None = Field(None, description="true: a Newton iteration that has stalled with its residual "
                                     "on a few unknowns (a point where the traction law bends on a scale below the "
                                     "corrections) solves those unknowns alone, every other held, then goes on "
                                     "(on MPI ranks too); false or unset: off")
    fallback: Literal["none", "implex"] = Field(
        "none", description="when a step fails at min_step: 'none' stops the run there (cleanly); 'implex' "
        "switches the EP cohesive surfaces to IMPL-EX integration for the rest of the run (logged) and goes on")


class OutputSection(_Section):
    points: bool = Field(True, description="write points.csv (per integration point and step)")
    vtk: bool = Field(False, description="write a ParaView time series (vtk/results.pvd)")
    vtk_every: Count = Field(1, description="write every n-th converged step to the series")
    checkpoint_every: int = Field(0, ge=0, le=10_000_000, description="save a checkpoint every n converged steps (0: never); "
                                  "rockfrac run --resume continues from the last one")
    separated_fraction: float = Field(0.01, gt=0.0, lt=1.0, description="a cohesive point counts as separated "
                                      "(history.csv's n_fragments and separated) once its tensile strength is below "
                                      "this fraction of its virgin one")
    picture: bool = Field(True, description="draw crack_map.png: the deformed mesh at the last converged step, "
                          "coloured by the plastic multiplier, with the yielded cracks coloured by their jump")
