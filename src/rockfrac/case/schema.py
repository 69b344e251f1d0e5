"""Schema of a case file (TOML); parameter names follow the paper's symbols, SI units, radians."""

from __future__ import annotations

import math
import tomllib
from enum import Enum
from pathlib import Path
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator


class CaseError(ValueError):
    """A case file problem, reported as 'file: [section] key: what is allowed'."""


class _Section(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class MeshKind(str, Enum):
    specimen = "specimen"


class ElementType(str, Enum):
    quad4 = "quad4"
    hex8 = "hex8"


class MeshSection(_Section):
    """The paper's specimen (PAPER_NOTES, Sect. 7): a W x H block under plane strain.

    element = "quad4": two blocks of nx x ny quads, cut by a crack through the centre at
    crack_angle (or merged, crack = false). element = "hex8": one block of nx x ny x nz hexahedra
    of thickness T with both out-of-plane faces held (plane strain), no crack (the EDE case).
    """

    kind: MeshKind = MeshKind.specimen
    element: ElementType = Field(ElementType.quad4, description="'quad4' (2D) or 'hex8' (3D, plane strain)")
    width: float = Field(0.04, gt=0, description="specimen width W [m]")
    height: float = Field(0.08, gt=0, description="specimen height H [m]")
    thickness: float | None = Field(None, gt=0, description="hex8 only: thickness T [m] (default 0.08)")
    crack: bool | None = Field(None, description="quad4 only: cut the specimen with a crack (default true)")
    crack_angle: float | None = Field(
        None, gt=-math.pi / 2, lt=math.pi / 2, description="crack angle from horizontal [rad] (default 60 deg)"
    )
    nx: int = Field(1, ge=1, description="elements across (each block)")
    ny: int = Field(1, ge=1, description="element layers (in each block for quad4)")
    nz: int | None = Field(None, ge=1, description="hex8 only: elements through the thickness (default 1)")

    @model_validator(mode="after")
    def _per_element(self) -> MeshSection:
        if self.element is ElementType.hex8:
            if self.crack:
                raise ValueError("element = 'hex8' cannot carry a cohesive crack (CSEs are 2D): use "
                                 "element = 'quad4' or crack = false")
            if self.crack_angle is not None:
                raise ValueError("crack_angle only applies to element = 'quad4' with a crack")
        else:
            given = [k for k in ("thickness", "nz") if getattr(self, k) is not None]
            if given:
                raise ValueError(f"{', '.join(given)} only apply to element = 'hex8'")
            if self.crack is False and self.crack_angle is not None:
                raise ValueError("crack_angle is given but crack = false")
        return self

    def resolved(self) -> MeshSection:
        """Every default filled in."""
        if self.element is ElementType.hex8:
            return self.model_copy(update={"thickness": self.thickness or 0.08, "nz": self.nz or 1, "crack": False})
        crack = True if self.crack is None else self.crack
        angle = (self.crack_angle if self.crack_angle is not None else math.radians(60.0)) if crack else None
        return self.model_copy(update={"crack": crack, "crack_angle": angle})


class BulkModel(str, Enum):
    elastic = "elastic"
    drucker_prager = "drucker_prager"


class BulkSection(_Section):
    """Bulk: linear isotropic elasticity, or nonassociative Drucker-Prager with linear hardening.

    F = sqrt(3/2)|s| + sqrt(3)(beta p - kappa0 - H gamma), G = sqrt(3/2)|s| + sqrt(3) b p,
    p = tr(sigma)/3 tension positive (rockfrac.laws.drucker_prager).
    """

    model: BulkModel = Field(BulkModel.elastic, description="'elastic' or 'drucker_prager'")
    E: float = Field(gt=0, description="Young's modulus [Pa]")
    nu: float = Field(gt=-1.0, lt=0.5, description="Poisson's ratio")
    beta: float | None = Field(None, ge=0, description="drucker_prager: friction coefficient of F [-]")
    b: float | None = Field(None, ge=0, description="drucker_prager: dilatancy coefficient of G [-]")
    kappa0: float | None = Field(None, ge=0, description="drucker_prager: initial strength kappa0 [Pa]")
    H: float | None = Field(None, description="drucker_prager: hardening modulus [Pa] (default 0; < 0 softens)")

    @model_validator(mode="after")
    def _model_keys(self) -> BulkSection:
        dp_keys = ("beta", "b", "kappa0", "H")
        if self.model is BulkModel.elastic:
            given = [k for k in dp_keys if getattr(self, k) is not None]
            if given:
                raise ValueError(f"{', '.join(given)} only apply to model = 'drucker_prager'")
            return self
        missing = [k for k in ("beta", "b", "kappa0") if getattr(self, k) is None]
        if missing:
            raise ValueError(f"model = 'drucker_prager' needs {', '.join(missing)}")
        from rockfrac.laws.drucker_prager_params import DruckerPrager

        DruckerPrager(self.E, self.nu, self.beta, self.b, self.kappa0, self.H or 0.0)  # admissible?
        return self

    def resolved(self) -> BulkSection:
        if self.model is BulkModel.drucker_prager and self.H is None:
            return self.model_copy(update={"H": 0.0})
        return self


class BandChoice(str, Enum):
    positive = "positive"
    negative = "negative"


class EmbeddedSection(_Section):
    """Embedded strong discontinuity (EDE, paper Sect. 4.1, 5): where det A = 0 is first reached, a
    surface through the element centre with the Mohr-Coulomb law and exponential softening in gamma."""

    c_p: float | Literal["eq28"] = Field(
        "eq28", description="peak cohesion [Pa], or 'eq28': from the stress at bifurcation (paper eq. 28)")
    c_r: float = Field(ge=0, description="residual cohesion [Pa]")
    phi_p: float = Field(ge=0, lt=math.pi / 2, description="peak friction angle [rad]")
    phi_r: float = Field(ge=0, lt=math.pi / 2, description="residual friction angle [rad]")
    psi_p: float = Field(ge=0, lt=math.pi / 2, description="peak dilation angle [rad]")
    alpha_c: float = Field(ge=0, description="softening rate of c [1/m]")
    alpha_phi: float = Field(ge=0, description="softening rate of phi [1/m]")
    alpha_psi: float = Field(ge=0, description="softening rate of psi [1/m]")
    band: BandChoice = Field(BandChoice.positive, description="which conjugate band: 'positive' (band "
                             "angle from horizontal in (0, 90) deg) or 'negative' ((-90, 0) deg)")

    @model_validator(mode="after")
    def _residual_below_peak(self) -> EmbeddedSection:
        if self.phi_r > self.phi_p or (self.c_p != "eq28" and self.c_r > self.c_p):
            raise ValueError("residual values (c_r, phi_r) must not exceed the peak ones")
        if self.c_p != "eq28" and self.c_p <= 0:
            raise ValueError("c_p must be > 0 or 'eq28'")
        return self


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
    embedded: EmbeddedSection | None = None
    loading: LoadingSection
    solver: SolverSection = SolverSection()
    output: OutputSection = OutputSection()

    @model_validator(mode="after")
    def _crack_needs_law(self) -> Case:
        crack = self.mesh.resolved().crack
        if self.loading.control is Control.path and not crack and self.embedded is None:
            raise ValueError("loading.control = 'path' follows a crack jump, but there is no crack")
        if crack and self.cohesive is None:
            raise ValueError("the mesh has a crack (mesh.crack = true) but there is no [cohesive] section")
        if not crack and self.cohesive is not None:
            raise ValueError("[cohesive] is given but mesh.crack = false: there is no surface to put it on")
        if self.embedded is not None and self.bulk.model is not BulkModel.drucker_prager:
            raise ValueError("[embedded] needs [bulk] model = 'drucker_prager' (bifurcation of eq. 7-8)")
        if self.embedded is not None and crack:
            raise ValueError("[embedded] and a cohesive crack on the same specimen: set mesh.crack = false")
        return self

    def resolved(self) -> Case:
        """The mesh and bulk sections with every default filled in."""
        return self.model_copy(update={"mesh": self.mesh.resolved(), "bulk": self.bulk.resolved()})


def _location(loc: tuple[Any, ...]) -> str:
    parts = [str(p) for p in loc if not str(p).startswith("function-")]
    if not parts:
        return "(top level)"
    if len(parts) == 1:
        return f"[{parts[0]}]" if parts[0] in ("mesh", "bulk", "cohesive", "embedded", "loading", "solver", "output", "law") else parts[0]
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
    return parse_case(read_toml(path), str(path))


class DriveLaw(TractionLaw):
    """A law for the material-point driver: the EP form, so kn and kt are required."""

    kn: float = Field(gt=0, description="normal penalty stiffness [Pa/m]")
    kt: float = Field(gt=0, description="tangential penalty stiffness [Pa/m]")


class LawFile(_Section):
    title: str = ""
    description: str = ""
    law: DriveLaw


def read_toml(path: str | Path) -> dict:
    """The TOML document of a file; CaseError if it is missing or not TOML."""
    path = Path(path)
    try:
        return tomllib.loads(path.read_text())
    except FileNotFoundError:
        raise CaseError(f"{path}: no such file") from None
    except tomllib.TOMLDecodeError as err:
        raise CaseError(f"{path}: not valid TOML: {err}") from None


def load_validated(path: str | Path, model: type[BaseModel]):
    """Read a TOML file into a schema ``model``; CaseError names the file, the key, what is allowed."""
    data = read_toml(path)
    try:
        return model.model_validate(data)
    except ValidationError as err:
        raise CaseError(format_errors(str(path), err, model)) from None


def load_law(path: str | Path) -> LawFile:
    """Read and validate a law file for ``rockfrac drive``."""
    return load_validated(path, LawFile)
