"""Schema of a case file (TOML); parameter names follow the paper's symbols, SI units, radians."""

from __future__ import annotations

import math
import tomllib
from enum import Enum
from pathlib import Path
from typing import Any, Literal

from pydantic import BaseModel, Field, ValidationError, field_validator, model_validator


from rockfrac.case.messages import format_errors
from rockfrac.case.types import (
    Angle,
    Coefficient,
    Coordinate,
    Count,
    Displacement,
    Energy,
    Fraction,
    Hardening,
    Length,
    Modulus,
    Rate,
    Stiffness,
    Strength,
)
from rockfrac.case.types import Section as _Section
from rockfrac.errors import CaseError
from rockfrac.files import read_text

__all__ = ["Case", "CaseError", "load_case", "parse_case"]


MAX_CELLS_ALONG = 100_000  # elements along one side of a generated mesh
MAX_CELLS = 20_000_000  # cells of a generated mesh


class MeshKind(str, Enum):
    specimen = "specimen"
    gmsh = "gmsh"
    grains = "grains"
    block = "block"


class ElementType(str, Enum):
    tri3 = "tri3"
    quad4 = "quad4"
    hex8 = "hex8"


MESH_KEYS = {  # keys of [mesh] beyond kind, element, width, height, per kind
    MeshKind.specimen: {"crack", "crack_angle", "nx", "ny", "thickness", "nz"},
    MeshKind.gmsh: {"file"},
    MeshKind.grains: {"n_grains", "radius_min", "radius_max", "seed", "element_size"},
    MeshKind.block: {"nx", "ny", "inclusion"},
}
OPTIONAL_MESH_KEYS = set().union(*MESH_KEYS.values())


class MeshSection(_Section):
    """The mesh: the paper's specimen, a Gmsh file, a generated grain specimen or a block.

    specimen: a W x H plane-strain block (PAPER_NOTES, Sect. 7); element = "quad4": two blocks of
    nx x ny quads cut by a crack through the centre at crack_angle (or one block, crack = false);
    "hex8": nx x ny x nz hexahedra of thickness T, both out-of-plane faces held, no crack.
    gmsh: a .msh file (2D tri3 or quad4, or hex8); physical groups name regions and boundaries.
    grains: n_grains circular stiff grains in a matrix (regions "grains", "matrix"), made by Gmsh.
    block: a W x H nx x ny grid, with an optional weak inclusion box (regions "weak", "bulk").
    Every kind provides the boundary groups bottom, top, left, right and bottom_left.
    """

    kind: MeshKind = Field(MeshKind.specimen, strict=False, description="'specimen', 'gmsh', 'grains' or 'block'")
    element: ElementType = Field(ElementType.quad4, strict=False, description="'tri3', 'quad4' (2D) or 'hex8' (3D, plane strain)")
    width: Length = Field(0.04, description="specimen width W [m]")
    height: Length = Field(0.08, description="specimen height H [m]")
    thickness: Length | None = Field(None, description="hex8 only: thickness T [m] (default 0.08)")
    crack: bool | None = Field(None, description="specimen, quad4: cut the specimen with a crack (default true)")
    crack_angle: float | None = Field(
        None, gt=-math.pi / 2, lt=math.pi / 2, description="crack angle from horizontal [rad] (default 60 deg)"
    )
    nx: Count | None = Field(None, le=MAX_CELLS_ALONG, description="elements across (in each block when cracked) (default 1)")
    ny: Count | None = Field(None, le=MAX_CELLS_ALONG, description="element layers (in each block when cracked) (default 1)")
    nz: Count | None = Field(None, le=MAX_CELLS_ALONG, description="hex8 only: elements through the thickness (default 1)")
    file: str | None = Field(None, description="gmsh: the .msh file (relative to the case file)")
    n_grains: Count | None = Field(None, le=100_000, description="grains: number of grains (default 60)")
    radius_min: Length | None = Field(None, description="grains: smallest grain radius [m] (default W/25)")
    radius_max: Length | None = Field(None, description="grains: largest grain radius [m] (default W/12)")
    seed: int | None = Field(None, ge=0, le=2**32 - 1, description="grains: random seed of the placement (default 0)")
    element_size: Length | None = Field(None, description="grains: target element size [m] (default W/40)")
    inclusion: list[Coordinate] | None = Field(None, description="block: weak region [x0, y0, x1, y1] [m]")

    @model_validator(mode="after")
    def _per_kind(self) -> MeshSection:
        allowed = MESH_KEYS[self.kind]
        given = sorted(k for k in OPTIONAL_MESH_KEYS - allowed if getattr(self, k) is not None)
        if given:
            raise ValueError(f"{', '.join(given)} do not apply to kind = '{self.kind.value}' "
                             f"(its keys: {', '.join(sorted(allowed))})")
        if self.kind is MeshKind.gmsh and self.file is None:
            raise ValueError("kind = 'gmsh' needs file (the .msh file)")
        if self.element is ElementType.hex8 and self.kind is not MeshKind.specimen:
            raise ValueError("element = 'hex8' is for kind = 'specimen' (a gmsh file brings its own cells)")
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
        if self.kind is MeshKind.specimen and self.element is ElementType.tri3:
            raise ValueError("kind = 'specimen' is made of quad4 or hex8 cells")
        cells = (self.nx or 1) * (self.ny or 1) * (self.nz or 1)
        if cells > MAX_CELLS:
            raise ValueError(f"nx x ny x nz = {cells} cells; at most {MAX_CELLS} (the limit of one machine's memory)")
        if self.kind is MeshKind.grains and self.element_size is not None:
            estimate = self.width * self.height / self.element_size**2
            if estimate > MAX_CELLS:
                raise ValueError(f"element_size = {self.element_size:g} m makes about {estimate:.3g} cells of "
                                 f"a {self.width:g} x {self.height:g} m block; at most {MAX_CELLS}")
        if self.radius_min is not None and self.radius_max is not None and self.radius_min > self.radius_max:
            raise ValueError("radius_min must not exceed radius_max")
        if self.inclusion is not None:
            x0, y0, x1, y1 = (self.inclusion + [math.nan] * 4)[:4]
            if len(self.inclusion) != 4 or not (0 <= x0 < x1 <= self.width and 0 <= y0 < y1 <= self.height):
                raise ValueError("inclusion must be [x0, y0, x1, y1] inside the block, x0 < x1, y0 < y1")
        return self

    def resolved(self) -> MeshSection:
        """Every default of the kind filled in."""
        k, w = self.kind, self.width
        if k is MeshKind.specimen and self.element is ElementType.hex8:
            return self.model_copy(update={"thickness": self.thickness or 0.08, "nz": self.nz or 1, "crack": False,
                                           "nx": self.nx or 1, "ny": self.ny or 1})
        if k is MeshKind.specimen:
            crack = True if self.crack is None else self.crack
            angle = (self.crack_angle if self.crack_angle is not None else math.radians(60.0)) if crack else None
            return self.model_copy(update={"crack": crack, "crack_angle": angle, "nx": self.nx or 1,
                                           "ny": self.ny or 1})
        if k is MeshKind.grains:
            return self.model_copy(update={"n_grains": self.n_grains or 60, "radius_min": self.radius_min or w / 25,
                                           "radius_max": self.radius_max or w / 12,
                                           "seed": self.seed if self.seed is not None else 0,
                                           "element_size": self.element_size or w / 40})
        if k is MeshKind.block:
            return self.model_copy(update={"nx": self.nx or 1, "ny": self.ny or 1})
        return self

    @property
    def has_crack(self) -> bool:
        """The specimen's own crack (the cohesive sets of other meshes are placed by [cohesive])."""
        return bool(self.resolved().crack)


class BulkModel(str, Enum):
    elastic = "elastic"
    drucker_prager = "drucker_prager"


class BulkSection(_Section):
    """Bulk: linear isotropic elasticity, or nonassociative Drucker-Prager with linear hardening.

    F = sqrt(3/2)|s| + sqrt(3)(beta p - kappa0 - H gamma), G = sqrt(3/2)|s| + sqrt(3) b p,
    p = tr(sigma)/3 tension positive (rockfrac.laws.drucker_prager).
    """

    model: BulkModel = Field(BulkModel.elastic, strict=False, description="'elastic' or 'drucker_prager'")
    E: Modulus = Field(description="Young's modulus [Pa]")
    nu: float = Field(gt=-1.0, lt=0.5, description="Poisson's ratio")
    beta: Coefficient | None = Field(None, description="drucker_prager: friction coefficient of F [-]")
    b: Coefficient | None = Field(None, description="drucker_prager: dilatancy coefficient of G [-]")
    kappa0: Strength | None = Field(None, description="drucker_prager: initial strength kappa0 [Pa]")
    H: Hardening | None = Field(None, description="drucker_prager: hardening modulus [Pa] (default 0; < 0 softens)")

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

        DruckerPrager(self.E, self.nu, self.beta, self.b, self.kappa0, self.H or 0.0)  # admissible? (ValueError)
        return self

    def resolved(self) -> BulkSection:
        if self.model is BulkModel.drucker_prager and self.H is None:
            return self.model_copy(update={"H": 0.0})
        return self


class MaterialSection(BulkSection):
    """A bulk material for the cells of one mesh region (several materials per model)."""

    region: str = Field(min_length=1, max_length=200, description="the mesh region (physical group) of this material")


class BandChoice(str, Enum):
    positive = "positive"
    negative = "negative"


class EmbeddedSection(_Section):
    """Embedded strong discontinuity (EDE, paper Sect. 4.1, 5): where det A = 0 is first reached, a
    surface through the element centre with the Mohr-Coulomb law and exponential softening in gamma."""

    c_p: Strength | Literal["eq28"] = Field(
        "eq28", description="peak cohesion [Pa], or 'eq28': from the stress at bifurcation (paper eq. 28)")
    c_r: Strength = Field(description="residual cohesion [Pa]")
    phi_p: Angle = Field(description="peak friction angle [rad]")
    phi_r: Angle = Field(description="residual friction angle [rad]")
    psi_p: Angle = Field(description="peak dilation angle [rad]")
    alpha_c: Rate = Field(description="softening rate of c [1/m]")
    alpha_phi: Rate = Field(description="softening rate of phi [1/m]")
    alpha_psi: Rate = Field(description="softening rate of psi [1/m]")
    band: BandChoice = Field(BandChoice.positive, strict=False, description="which conjugate band: 'positive' (band "
                             "angle from horizontal in (0, 90) deg) or 'negative' ((-90, 0) deg)")
    tracking: Literal["none", "local"] = Field(
        "none", description="'none': each cell's surface through its centroid (the paper's Tahoe element); "
        "'local': a cell next to a cut cell continues that cell's surface (a continuous crack path)")
    regions: list[str] | None = Field(None, description="regions that may localize (default: every "
                                      "drucker_prager region)")
    max_cracks: Count = Field(1, description="tracking = 'local': most cracks started; further cuts "
                            "continue them from their tips")

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


class WorkRule(str, Enum):
    backward_euler = "backward_euler"
    trapezoidal = "trapezoidal"


class TractionLaw(_Section):
    """Parameters of the traction law of Sect. 4.2 (Table 1 symbols)."""

    GfI: Energy = Field(description="mode I fracture energy [J/m^2]")
    GfII: Energy = Field(description="mode II fracture energy [J/m^2]")
    chi_p: Strength = Field(description="peak tensile strength [Pa]")
    chi_r: Strength = Field(description="residual tensile strength [Pa]")
    c_p: Strength = Field(description="peak cohesion [Pa]")
    c_r: Strength = Field(description="residual cohesion [Pa]")
    phi_p: Angle = Field(description="peak friction angle [rad]")
    phi_r: Angle = Field(description="residual friction angle [rad]")
    psi_p: Angle = Field(description="peak dilation angle [rad]")
    alpha_chi: Rate = Field(description="softening rate of chi [-]")
    alpha_c: Rate = Field(description="softening rate of c [-]")
    alpha_phi: Rate = Field(description="softening rate of tan(phi) [-]")
    alpha_psi: Rate = Field(description="softening rate of tan(psi) [-]")
    work_rule: WorkRule = Field(WorkRule.backward_euler, strict=False, description="work that drives softening in a step: "
                                "'backward_euler' (the paper's: end traction x plastic jump increment; first "
                                "order in the step) or 'trapezoidal' (mean of the traction where flow starts "
                                "and the end traction; second order)")

    @model_validator(mode="after")
    def _residual_below_peak(self):
        if self.chi_r > self.chi_p or self.c_r > self.c_p or self.phi_r > self.phi_p:
            raise ValueError("residual values (chi_r, c_r, phi_r) must not exceed the peak ones")
        return self


class Placement(str, Enum):
    crack = "crack"
    between = "between"
    within = "within"
    curves = "curves"
    all = "all"


class CohesiveSection(TractionLaw):
    """Traction law of Sect. 4.2, the cohesive-surface form (EP penalty or RP multipliers) and where
    the surfaces go: the specimen's crack, between two regions (grain/matrix), on every internal
    edge within a region, along named curves, or on every internal edge."""

    form: CohesiveForm = Field(strict=False, description="'ep' (elasto-plastic, penalty kn, kt) or 'rp' "
                               "(rigid-plastic, augmented Lagrange multipliers)")
    where: Placement = Field(Placement.crack, strict=False, description="'crack' (the specimen's), 'between' (two "
                             "regions), 'within' (a region), 'curves' (named curves) or 'all'")
    regions: list[str] | None = Field(None, description="between: two regions (the first is the minus side); "
                                      "within: one region")
    curves: list[str] | None = Field(None, description="curves: names of curve groups (edge sets)")
    kn: Stiffness | None = Field(None, description="EP only: normal penalty stiffness [Pa/m]")
    kt: Stiffness | None = Field(None, description="EP only: tangential penalty stiffness [Pa/m]")
    augmentation: Stiffness | None = Field(None, description="RP only: augmentation r [Pa/m]")

    @model_validator(mode="after")
    def _placement(self) -> CohesiveSection:
        need = {Placement.between: 2, Placement.within: 1}
        if self.where in need and (self.regions is None or len(self.regions) != need[self.where]):
            raise ValueError(f"where = '{self.where.value}' needs regions = a list of {need[self.where]} region name(s)")
        if self.where not in need and self.regions is not None:
            raise ValueError(f"regions only apply to where = 'between' or 'within', not '{self.where.value}'")
        if (self.where is Placement.curves) != (self.curves is not None):
            raise ValueError("curves go with where = 'curves' (a list of curve group names)")
        return self

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

    confinement: Strength = Field(description="lateral confining pressure [Pa]")
    confinement_steps: Count = Field(1, description="steps of the confinement stage")
    axial_displacement: Displacement | list[Displacement] = Field(
        description="top shortening [m] at the end of the axial stage (negative: extension); a list "
        "gives successive targets (load, unload, reload...), each reached in axial_steps steps")
    axial_steps: Count = Field(description="steps of each axial stage")
    control: Control = Field(Control.displacement, strict=False, description="'displacement' or 'path'")
    path_increment: Length | None = Field(None, description="path control: mean-jump increment [m]")
    max_steps: Count | None = Field(None, description="path control: most axial steps")
    stop_below_peak_fraction: Fraction | None = Field(
        None, description="stop once F_axial falls below this fraction of its peak"
    )
    support: str = Field("bottom", description="node group held in y (and in z for hex8 faces)")
    pin: str = Field("bottom_left", description="node group held in x")
    axial: str = Field("top", description="node group whose y displacement is prescribed (F_axial is its reaction)")
    pressure: list[str] = Field(["left", "right"], description="boundary edge (face) groups under the confinement")

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
    auto = "auto"
    superlu = "superlu"
    pardiso = "pardiso"
    mumps = "mumps"
    gmres_amg = "gmres-amg"


class SolverSection(_Section):
    linear: LinearSolverName = Field(LinearSolverName.auto, strict=False,
                                     description="'auto' (the fastest installed: pardiso, mumps, superlu), "
                                     "'superlu' (SciPy), 'pardiso' (needs pypardiso), 'mumps' (needs "
                                     "python-mumps) or 'gmres-amg' (iterative, needs pyamg)")

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


class OutputSection(_Section):
    points: bool = Field(True, description="write points.csv (per integration point and step)")
    vtk: bool = Field(False, description="write a ParaView time series (vtk/results.pvd)")
    vtk_every: Count = Field(1, description="write every n-th converged step to the series")
    checkpoint_every: int = Field(0, ge=0, le=10_000_000, description="save a checkpoint every n converged steps (0: never); "
                                  "rockfrac run --resume continues from the last one")
    picture: bool = Field(True, description="draw crack_map.png: the deformed mesh at the last converged step, "
                          "coloured by the plastic multiplier, with the yielded cracks coloured by their jump")


class Case(_Section):
    title: str = Field("", max_length=1000, description="one line naming the case")
    description: str = Field("", max_length=100_000, description="what the case is, free text")
    mesh: MeshSection = MeshSection()
    bulk: BulkSection | None = None
    materials: list[MaterialSection] | None = None
    cohesive: list[CohesiveSection] | None = None  # one [cohesive] table is read as a list of one
    embedded: EmbeddedSection | None = None
    loading: LoadingSection
    solver: SolverSection = SolverSection()
    output: OutputSection = OutputSection()

    @field_validator("cohesive", mode="before")
    @classmethod
    def _one_or_many(cls, value: Any) -> Any:
        return [value] if isinstance(value, dict) else value

    @property
    def cohesive_sets(self) -> list[CohesiveSection]:
        """The cohesive sections ([cohesive] or several [[cohesive]])."""
        return list(self.cohesive or [])

    @property
    def material_list(self) -> list[BulkSection]:
        """Every bulk material ([bulk] for all cells, or the [[materials]] per region)."""
        return [self.bulk] if self.bulk is not None else list(self.materials or [])

    @model_validator(mode="after")
    def _consistent(self) -> Case:
        if (self.bulk is None) == (self.materials is None):
            raise ValueError("give either [bulk] (one material everywhere) or [[materials]] (one per region), "
                             "not both or neither")
        regions = [m.region for m in self.materials or []]
        if len(set(regions)) != len(regions):
            raise ValueError(f"[[materials]]: each region once (got {regions})")
        crack = self.mesh.has_crack
        sets = self.cohesive_sets
        on_crack = [c for c in sets if c.where is Placement.crack]
        if crack and len(on_crack) != 1:
            raise ValueError("the specimen has a crack (mesh.crack = true): give one [cohesive] section for it")
        if on_crack and not crack:
            raise ValueError("[cohesive] where = 'crack' needs the specimen's crack (kind = 'specimen', crack = true); "
                             "elsewhere say where the surfaces go (between, within, curves, all)")
        if sets and self.mesh.element is ElementType.hex8:
            raise ValueError("cohesive surfaces are 2D: not with element = 'hex8'")
        dp = [m for m in self.material_list if m.model is BulkModel.drucker_prager]
        if self.embedded is not None and not dp:
            raise ValueError("[embedded] needs a drucker_prager material (bifurcation of eq. 7-8)")
        if self.embedded is not None and crack:
            raise ValueError("[embedded] and a cohesive crack on the same specimen: set mesh.crack = false")
        if self.loading.control is Control.path and not sets and self.embedded is None:
            raise ValueError("loading.control = 'path' follows a crack jump, but there is no cohesive surface "
                             "and no [embedded] section")
        return self

    def resolved(self) -> Case:
        """The mesh and material sections with every default filled in."""
        update = {"mesh": self.mesh.resolved()}
        if self.bulk is not None:
            update["bulk"] = self.bulk.resolved()
        else:
            update["materials"] = [m.resolved() for m in self.materials]
        return self.model_copy(update=update)


def _arrays(data: Any) -> frozenset:
    """Top-level keys given as arrays of tables ([[materials]]...): their errors say '[materials 2]'."""
    if not isinstance(data, dict):
        return frozenset()
    return frozenset(k for k, v in data.items() if isinstance(v, list) and v and isinstance(v[0], dict))


def parse_case(data: dict, path: str = "<case>") -> Case:
    """Validate a case dictionary; raises CaseError naming file, key and what is allowed."""
    try:
        return Case.model_validate(data)
    except ValidationError as err:
        raise CaseError(format_errors(path, err, Case, _arrays(data))) from None


def load_case(path: str | Path) -> Case:
    """Read and validate a case file; a relative mesh file is taken relative to the case file."""
    data = read_toml(path, "a case file")
    mesh = data.get("mesh")
    if isinstance(mesh, dict) and isinstance(mesh.get("file"), str) and not Path(mesh["file"]).is_absolute():
        data["mesh"] = dict(mesh, file=str((Path(path).parent / mesh["file"]).resolve()))
    return parse_case(data, str(path))


class DriveLaw(TractionLaw):
    """A law for the material-point driver: the EP form, so kn and kt are required."""

    kn: Stiffness = Field(description="normal penalty stiffness [Pa/m]")
    kt: Stiffness = Field(description="tangential penalty stiffness [Pa/m]")


class LawFile(_Section):
    title: str = ""
    description: str = ""
    law: DriveLaw


def read_toml(path: str | Path, what: str = "a TOML file") -> dict:
    """The TOML document of a file; CaseError if it cannot be read or is not TOML."""
    text = read_text(path, f"{what} (TOML text)")
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        raise CaseError(f"{path}: not valid TOML: {err}") from None


def load_validated(path: str | Path, model: type[BaseModel], what: str = "an input file"):
    """Read a TOML file into a schema ``model``; CaseError names the file, the key, what is allowed."""
    data = read_toml(path, what)
    try:
        return model.model_validate(data)
    except ValidationError as err:
        raise CaseError(format_errors(str(path), err, model, _arrays(data))) from None


def load_law(path: str | Path) -> LawFile:
    """Read and validate a law file for ``rockfrac drive``."""
    return load_validated(path, LawFile, "a law file")
