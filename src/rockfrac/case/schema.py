"""Schema of a case file (TOML); parameter names follow the paper's symbols, SI units, radians."""

from __future__ import annotations

import math
import tomllib
from enum import Enum
from pathlib import Path
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator


class CaseError(ValueError):
    """A case file problem, reported as 'file: [section] key: what is allowed'."""


class _Section(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


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

    kind: MeshKind = MeshKind.specimen
    element: ElementType = Field(ElementType.quad4, description="'tri3', 'quad4' (2D) or 'hex8' (3D, plane strain)")
    width: float = Field(0.04, gt=0, description="specimen width W [m]")
    height: float = Field(0.08, gt=0, description="specimen height H [m]")
    thickness: float | None = Field(None, gt=0, description="hex8 only: thickness T [m] (default 0.08)")
    crack: bool | None = Field(None, description="specimen, quad4: cut the specimen with a crack (default true)")
    crack_angle: float | None = Field(
        None, gt=-math.pi / 2, lt=math.pi / 2, description="crack angle from horizontal [rad] (default 60 deg)"
    )
    nx: int | None = Field(None, ge=1, description="elements across (in each block when cracked) (default 1)")
    ny: int | None = Field(None, ge=1, description="element layers (in each block when cracked) (default 1)")
    nz: int | None = Field(None, ge=1, description="hex8 only: elements through the thickness (default 1)")
    file: str | None = Field(None, description="gmsh: the .msh file (relative to the case file)")
    n_grains: int | None = Field(None, ge=1, description="grains: number of grains (default 60)")
    radius_min: float | None = Field(None, gt=0, description="grains: smallest grain radius [m] (default W/25)")
    radius_max: float | None = Field(None, gt=0, description="grains: largest grain radius [m] (default W/12)")
    seed: int | None = Field(None, ge=0, description="grains: random seed of the placement (default 0)")
    element_size: float | None = Field(None, gt=0, description="grains: target element size [m] (default W/40)")
    inclusion: list[float] | None = Field(None, description="block: weak region [x0, y0, x1, y1] [m]")

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


class MaterialSection(BulkSection):
    """A bulk material for the cells of one mesh region (several materials per model)."""

    region: str = Field(description="the mesh region (physical group) of this material")


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
    tracking: Literal["none", "local"] = Field(
        "none", description="'none': each cell's surface through its centroid (the paper's Tahoe element); "
        "'local': a cell next to a cut cell continues that cell's surface (a continuous crack path)")
    regions: list[str] | None = Field(None, description="regions that may localize (default: every "
                                      "drucker_prager region)")
    max_cracks: int = Field(1, ge=1, description="tracking = 'local': most cracks started; further cuts "
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
    work_rule: WorkRule = Field(WorkRule.backward_euler, description="work that drives softening in a step: "
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

    form: CohesiveForm
    where: Placement = Field(Placement.crack, description="'crack' (the specimen's), 'between' (two "
                             "regions), 'within' (a region), 'curves' (named curves) or 'all'")
    regions: list[str] | None = Field(None, description="between: two regions (the first is the minus side); "
                                      "within: one region")
    curves: list[str] | None = Field(None, description="curves: names of curve groups (edge sets)")
    kn: float | None = Field(None, gt=0, description="EP only: normal penalty stiffness [Pa/m]")
    kt: float | None = Field(None, gt=0, description="EP only: tangential penalty stiffness [Pa/m]")
    augmentation: float | None = Field(None, gt=0, description="RP only: augmentation r [Pa/m]")

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
    linear: LinearSolverName = Field(LinearSolverName.auto,
                                     description="'auto' (the fastest installed: pardiso, mumps, superlu), "
                                     "'superlu' (SciPy), 'pardiso' (needs pypardiso), 'mumps' (needs "
                                     "python-mumps) or 'gmres-amg' (iterative, needs pyamg)")

    @model_validator(mode="after")
    def _solver_installed(self) -> SolverSection:
        from rockfrac.solve.linear import available

        if self.linear.value != "auto" and self.linear.value not in available():
            raise ValueError(f"linear = {self.linear.value!r} is not installed here; available: {available()}")
        return self
    max_iterations: int = Field(25, ge=1)
    tol_residual: float = Field(1e-8, gt=0)
    tol_energy: float = Field(1e-10, gt=0)
    cutback: float = Field(0.5, gt=0, lt=1)
    min_step: float = Field(1e-4, gt=0, le=1, description="smallest increment, fraction of the nominal")


class OutputSection(_Section):
    points: bool = Field(True, description="write points.csv (per integration point and step)")
    vtk: bool = Field(False, description="write a ParaView time series (vtk/results.pvd)")
    vtk_every: int = Field(1, ge=1, description="write every n-th converged step to the series")
    checkpoint_every: int = Field(0, ge=0, description="save a checkpoint every n converged steps (0: never); "
                                  "rockfrac run --resume continues from the last one")
    picture: bool = Field(True, description="draw crack_map.png: the deformed mesh at the last converged step, "
                          "coloured by the plastic multiplier, with the yielded cracks coloured by their jump")


class Case(_Section):
    title: str = ""
    description: str = ""
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


SECTIONS = ("mesh", "bulk", "materials", "cohesive", "embedded", "loading", "solver", "output", "law", "material",
            "stress")


def _location(loc: tuple[Any, ...], arrays: frozenset = frozenset()) -> str:
    """'[section] key', or '[section N] key' (N 1-based) for a section given as an array of tables."""
    parts = [p for p in loc if not str(p).startswith("function-")]
    if not parts:
        return "(top level)"
    head, rest = str(parts[0]), parts[1:]
    if rest and isinstance(rest[0], int):
        head, rest = (f"{head} {rest[0] + 1}" if head in arrays else head), rest[1:]
    if not rest:
        return f"[{head}]" if str(parts[0]) in SECTIONS else head
    return f"[{head}] {'.'.join(str(p) for p in rest)}"


def format_errors(path: str, err: ValidationError, root: Any = None, arrays: frozenset = frozenset()) -> str:
    """One line per problem: file, section and key, what is allowed (arrays: sections given as lists)."""
    lines = []
    for e in err.errors():
        where = _location(e["loc"], arrays)
        if e["type"] == "extra_forbidden":
            allowed = ", ".join(_section_model(root or Case, e["loc"][:-1]).model_fields)
            lines.append(f"{path}: {where}: unknown key; allowed keys: {allowed}")
        elif e["type"] == "missing" and len(e["loc"]) == 1 and isinstance(e["loc"][0], str):
            lines.append(f"{path}: missing section [{e['loc'][0]}]")
        elif e["type"] == "missing":
            lines.append(f"{path}: {where}: missing (required)")
        else:
            got = f" (got {e['input']!r})" if not isinstance(e.get("input"), (dict, list)) else ""
            msg = e["msg"].removeprefix("Value error, ")
            lines.append(f"{path}: {where}: {msg}{got}")
    return "\n".join(lines)


def _section_model(model: Any, loc: tuple) -> Any:
    """The schema class at a location (through optional, list and union annotations)."""
    import typing

    for part in loc:
        if isinstance(part, int) or str(part).startswith("function-"):
            continue
        ann = model.model_fields[part].annotation
        while True:  # unwrap X | None, list[X], X | list[X] down to a model class
            args = [a for a in typing.get_args(ann) if a is not type(None)]
            if isinstance(ann, type) and issubclass(ann, BaseModel):
                break
            ann = next((a for a in args if isinstance(a, type) and issubclass(a, BaseModel)), args[0])
        model = ann
    return model


def parse_case(data: dict, path: str = "<case>") -> Case:
    """Validate a case dictionary; raises CaseError naming file, key and what is allowed."""
    try:
        return Case.model_validate(data)
    except ValidationError as err:
        arrays = frozenset(k for k, v in data.items() if isinstance(v, list) and v and isinstance(v[0], dict))
        raise CaseError(format_errors(path, err, arrays=arrays)) from None


def load_case(path: str | Path) -> Case:
    """Read and validate a case file; a relative mesh file is taken relative to the case file."""
    data = read_toml(path)
    mesh = data.get("mesh")
    if isinstance(mesh, dict) and isinstance(mesh.get("file"), str) and not Path(mesh["file"]).is_absolute():
        data["mesh"] = dict(mesh, file=str((Path(path).parent / mesh["file"]).resolve()))
    return parse_case(data, str(path))


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
