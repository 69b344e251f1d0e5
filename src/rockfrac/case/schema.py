"""Schema of a case file (TOML); parameter names follow the paper's symbols, SI units, radians."""

from __future__ import annotations

import math
import tomllib
from enum import Enum
from pathlib import Path
from typing import Any

from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator


class CaseError(ValueError):
    """A case file problem, reported as 'file: [section] key: what is allowed'."""


class _Section(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class MeshKind(str, Enum):
    specimen = "specimen"


class MeshSection(_Section):
    """The paper's specimen: W x H block, crack through the centre (PAPER_NOTES, Sect. 7)."""

    kind: MeshKind = MeshKind.specimen
    width: float = Field(0.04, gt=0, description="specimen width W [m]")
    height: float = Field(0.08, gt=0, description="specimen height H [m]")
    crack: bool = Field(True, description="cut the specimen with a crack (False: uncracked block)")
    crack_angle: float = Field(
        math.radians(60.0), gt=-math.pi / 2, lt=math.pi / 2, description="crack angle from horizontal [rad]"
    )
    nx: int = Field(1, ge=1, description="elements across each block")
    ny: int = Field(1, ge=1, description="element layers in each block")


class BulkSection(_Section):
    """Linear isotropic elastic bulk (plane strain)."""

    E: float = Field(gt=0, description="Young's modulus [Pa]")
    nu: float = Field(gt=-1.0, lt=0.5, description="Poisson's ratio")


class CohesiveForm(str, Enum):
    ep = "ep"
    rp = "rp"


class TractionLaw(_Section):
    """Parameters of the traction law of Sect. 4.2 (Table 1 symbols)."""

    GfI: float = Field(gt=0, description="mode I fracture energy [J/m^2]")
    GfII: float = Field(gt=0, description="mode II fracture energy [J/m^2]")
    chi_p: float = Field(ge=0, description="peak tensile strength [Pa]")
    chi_r: float = Field(ge=0, description="residual tensile strength [Pa]")
    c_p: float = Field(ge=0, description="peak cohesion [Pa]")
    c_r: float = Field(ge=0, description="residual cohesion [Pa]")
    phi_p: float = Field(ge=0, lt=math.pi / 2, description="peak friction angle [rad]")
    phi_r: float = Field(ge=0, lt=math.pi / 2, description="residual friction angle [rad]")
    psi_p: float = Field(ge=0, lt=math.pi / 2, description="peak dilation angle [rad]")
    alpha_chi: float = Field(ge=0, description="softening rate of chi [-]")
    alpha_c: float = Field(ge=0, description="softening rate of c [-]")
    alpha_phi: float = Field(ge=0, description="softening rate of tan(phi) [-]")
    alpha_psi: float = Field(ge=0, description="softening rate of tan(psi) [-]")
    @model_validator(mode="after")
    def _residual_below_peak(self):
        if self.chi_r > self.chi_p or self.c_r > self.c_p or self.phi_r > self.phi_p:
            raise ValueError("residual values (chi_r, c_r, phi_r) must not exceed the peak ones")
        return self


class CohesiveSection(TractionLaw):
    """Traction law of Sect. 4.2 and the cohesive-surface form (EP penalty or RP multipliers)."""

    form: CohesiveForm
    kn: float | None = Field(None, gt=0, description="EP only: normal penalty stiffness [Pa/m]")
    kt: float | None = Field(None, gt=0, description="EP only: tangential penalty stiffness [Pa/m]")
    augmentation: float | None = Field(None, gt=0, description="RP only: augmentation r [Pa/m]")

    @model_validator(mode="after")
    def _form_keys(self) -> CohesiveSection:
        if self.form is CohesiveForm.ep:
            missing = [k for k in ("kn", "kt") if getattr(self, k) is None]
            if missing:
                raise ValueError(f"form = 'ep' needs {', '.join(missing)} (penalty stiffness, Pa/m)")
            extra = [k for k in ("augmentation",) if getattr(self, k) is not None]
            if extra:
                raise ValueError("augmentation only applies to form = 'rp'")
        else:
            extra = [k for k in ("kn", "kt") if getattr(self, k) is not None]
            if extra:
                raise ValueError(f"{', '.join(extra)} only apply to form = 'ep' (RP has no elastic jump)")
        return self


class Control(str, Enum):
    displacement = "displacement"
    path = "path"


class LoadingSection(_Section):
    """Confinement first (then held), then top shortening.

    control = "displacement": every axial step prescribes the top displacement.
    control = "path": displacement control until the cohesive surface yields, then each step
    prescribes an increment ``path_increment`` of the mean crack jump and solves for the top
    displacement (indirect displacement control: traces the peak and any snap-back).
    """

    confinement: float = Field(ge=0, description="lateral confining pressure [Pa]")
    confinement_steps: int = Field(1, ge=1)
    axial_displacement: float | list[float] = Field(
        description="top shortening [m] at the end of the axial stage (negative: extension); a list "
        "gives successive targets (load, unload, reload...), each reached in axial_steps steps")
    axial_steps: int = Field(ge=1)
    control: Control = Control.displacement
    path_increment: float | None = Field(None, gt=0, description="path control: mean-jump increment [m]")
    max_steps: int | None = Field(None, ge=1, description="path control: most axial steps")
    stop_below_peak_fraction: float | None = Field(
        None, gt=0, lt=1, description="stop once F_axial falls below this fraction of its peak"
    )

    @property
    def axial_targets(self) -> list[float]:
        """Successive top-shortening targets [m]."""
        a = self.axial_displacement
        return list(a) if isinstance(a, list) else [a]

    @model_validator(mode="after")
    def _targets(self) -> LoadingSection:
        t = self.axial_targets
        if not t:
            raise ValueError("axial_displacement: give at least one target")
        if self.control is Control.path and len(t) > 1:
            raise ValueError("control = 'path' follows a monotonic crack opening: use one axial_displacement")
        return self


class LinearSolverName(str, Enum):
    superlu = "superlu"
    pardiso = "pardiso"


class SolverSection(_Section):
    linear: LinearSolverName = Field(LinearSolverName.superlu,
                                     description="'superlu' (SciPy) or 'pardiso' (needs pypardiso)")

    @model_validator(mode="after")
    def _solver_installed(self) -> SolverSection:
        from rockfrac.solve.linear import available

        if self.linear.value not in available():
            raise ValueError(f"linear = {self.linear.value!r} is not installed here; available: {available()}")
        return self
    max_iterations: int = Field(25, ge=1)
    tol_residual: float = Field(1e-8, gt=0)
    tol_energy: float = Field(1e-10, gt=0)
    cutback: float = Field(0.5, gt=0, lt=1)
    min_step: float = Field(1e-4, gt=0, le=1, description="smallest increment, fraction of the nominal")


class OutputSection(_Section):
    points: bool = Field(True, description="write points.csv (per integration point and step)")


class Case(_Section):
    title: str = ""
    description: str = ""
    mesh: MeshSection = MeshSection()
    bulk: BulkSection
    cohesive: CohesiveSection | None = None
    loading: LoadingSection
    solver: SolverSection = SolverSection()
    output: OutputSection = OutputSection()

    @model_validator(mode="after")
    def _crack_needs_law(self) -> Case:
        if self.loading.control is Control.path and not self.mesh.crack:
            raise ValueError("loading.control = 'path' follows the crack jump, but mesh.crack = false")
        if self.mesh.crack and self.cohesive is None:
            raise ValueError("the mesh has a crack (mesh.crack = true) but there is no [cohesive] section")
        if not self.mesh.crack and self.cohesive is not None:
            raise ValueError("[cohesive] is given but mesh.crack = false: there is no surface to put it on")
        return self


def _location(loc: tuple[Any, ...]) -> str:
    parts = [str(p) for p in loc if not str(p).startswith("function-")]
    if not parts:
        return "(top level)"
    if len(parts) == 1:
        return f"[{parts[0]}]" if parts[0] in ("mesh", "bulk", "cohesive", "loading", "solver", "output", "law") else parts[0]
    return f"[{parts[0]}] {'.'.join(parts[1:])}"


def format_errors(path: str, err: ValidationError, root: Any = None) -> str:
    """One line per problem: file, section and key, what is allowed."""
    lines = []
    for e in err.errors():
        where = _location(e["loc"])
        if e["type"] == "extra_forbidden":
            section = e["loc"][:-1]
            model: Any = root or Case
            for part in section:
                model = model.model_fields[part].annotation
                model = getattr(model, "__args__", (model,))[0]
            allowed = ", ".join(model.model_fields)
            lines.append(f"{path}: {where}: unknown key; allowed keys: {allowed}")
        elif e["type"] == "missing" and len(e["loc"]) == 1 and isinstance(e["loc"][0], str):
            lines.append(f"{path}: missing section [{e['loc'][0]}]")
        elif e["type"] == "missing":
            lines.append(f"{path}: {where}: missing (required)")
        else:
            got = f" (got {e['input']!r})" if not isinstance(e.get("input"), dict) else ""
            lines.append(f"{path}: {where}: {e['msg']}{got}")
    return "\n".join(lines)


def parse_case(data: dict, path: str = "<case>") -> Case:
    """Validate a case dictionary; raises CaseError naming file, key and what is allowed."""
    try:
        return Case.model_validate(data)
    except ValidationError as err:
        raise CaseError(format_errors(path, err)) from None


def load_case(path: str | Path) -> Case:
    """Read and validate a case file."""
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text())
    except FileNotFoundError:
        raise CaseError(f"{path}: no such file") from None
    except tomllib.TOMLDecodeError as err:
        raise CaseError(f"{path}: not valid TOML: {err}") from None
    return parse_case(data, str(path))


class DriveLaw(TractionLaw):
    """A law for the material-point driver: the EP form, so kn and kt are required."""

    kn: float = Field(gt=0, description="normal penalty stiffness [Pa/m]")
    kt: float = Field(gt=0, description="tangential penalty stiffness [Pa/m]")


class LawFile(_Section):
    title: str = ""
    description: str = ""
    law: DriveLaw


def load_law(path: str | Path) -> LawFile:
    """Read and validate a law file for ``rockfrac drive``."""
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text())
    except FileNotFoundError:
        raise CaseError(f"{path}: no such file") from None
    except tomllib.TOMLDecodeError as err:
        raise CaseError(f"{path}: not valid TOML: {err}") from None
    try:
        return LawFile.model_validate(data)
    except ValidationError as err:
        raise CaseError(format_errors(str(path), err, LawFile)) from None
