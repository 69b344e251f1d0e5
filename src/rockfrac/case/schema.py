"""Schema of a case file (TOML); parameter names follow the paper's symbols, SI units, radians.

A case is the serialisation of the objects a run is built from; each section has its own module:
[mesh] (:mod:`.mesh_section`), [bulk]/[[materials]]/[embedded] (:mod:`.materials`), [cohesive]
(:mod:`.cohesive_section`), the loading program [[stages]] with [initial] and [[monitors]]
(:mod:`.program`) or the paper's short form [loading] (:mod:`.loading`), [solver] and [output]
(:mod:`.solver_section`).
"""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, Literal, Union

from pydantic import (
    BaseModel,
    Discriminator,
    Field,
    Tag,
    ValidationError,
    field_validator,
    model_validator,
)

from rockfrac.case.cohesive_section import (
    AnyCohesiveSection,
    CohesiveCommon,
    CohesiveForm,
    CohesiveSection,
    Placement,
    TractionLawSection,
    WorkRule,
)
from rockfrac.case.loading import Control, LoadingSection
from rockfrac.case.materials import (
    BandChoice,
    BulkModel,
    BulkSection,
    EmbeddedSection,
    MaterialSection,
)
from rockfrac.case.mesh_section import ElementType, MeshKind, MeshSection
from rockfrac.case.messages import format_errors
from rockfrac.case.program import InitialSection, MonitorSection, StageSection, StopSection
from rockfrac.case.solver_section import LinearSolverName, OutputSection, SolverSection
from rockfrac.errors import CaseError
from rockfrac.files import read_text
from rockfrac.laws.registry import DEFAULT as DEFAULT_LAW
from rockfrac.laws.registry import LAWS
from rockfrac.values import Section as _Section
from rockfrac.values import Stiffness

__all__ = ["BandChoice", "BulkModel", "BulkSection", "Case", "CaseError", "CohesiveForm", "CohesiveSection",
           "Control", "ElementType", "EmbeddedSection", "InitialSection", "LinearSolverName", "LoadingSection",
           "MaterialSection", "MeshKind", "MeshSection", "MonitorSection", "OutputSection", "Placement",
           "SolverSection", "StageSection", "StopSection", "TractionLawSection", "WorkRule", "load_case", "parse_case"]


class Case(_Section):
    title: str = Field("", max_length=1000, description="one line naming the case")
    description: str = Field("", max_length=100_000, description="what the case is, free text")
    mesh: MeshSection = MeshSection()
    bulk: BulkSection | None = None
    materials: list[MaterialSection] | None = None
    cohesive: list[AnyCohesiveSection] | None = None  # one [cohesive] table is read as a list of one
    embedded: EmbeddedSection | None = None
    loading: LoadingSection | None = Field(None, description="the paper's loading program (confinement, then "
                                           "axial shortening); or give [[stages]]")
    stages: list[StageSection] | None = Field(None, description="the loading program: stages on named groups")
    initial: InitialSection | None = Field(None, description="the state at t = 0: gravity, in-situ stress")
    monitors: list[MonitorSection] | None = Field(None, description="point displacements and openings to follow")
    solver: SolverSection = SolverSection()
    output: OutputSection = OutputSection()

    @field_validator("cohesive", mode="before")
    @classmethod
    def _one_or_many(cls, value: Any) -> Any:
        return [value] if isinstance(value, dict) else value

    @property
    def cohesive_sets(self) -> list[CohesiveCommon]:
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
        if sets and self.mesh.element.solid and self.mesh.kind is not MeshKind.gmsh:
            raise ValueError(f"cohesive surfaces of a generated 3D mesh are not made: not with element = "
                             f"'{self.mesh.element.value}' (3D cohesive surfaces: a gmsh mesh of tet4 cells)")
        dp = [m for m in self.material_list if m.model is BulkModel.drucker_prager]
        if self.embedded is not None and not dp:
            raise ValueError("[embedded] needs a drucker_prager material (bifurcation of eq. 7-8)")
        if self.embedded is not None and crack:
            raise ValueError("[embedded] and a cohesive crack on the same specimen: set mesh.crack = false")
        if (self.loading is None) == (self.stages is None):
            raise ValueError("give the loading program: either [[stages]] or the paper's short form [loading], "
                             "not both" if self.loading is not None else "missing: the loading program "
                             "([[stages]], or the paper's short form [loading])")
        paths = [s for s in self.stages or [] if s.control == "path"]
        path = (self.loading is not None and self.loading.control is Control.path) or bool(paths)
        if path and not sets and self.embedded is None:
            raise ValueError("control = 'path' follows a crack jump, but there is no cohesive surface "
                             "and no [embedded] section")
        if self.stages is not None and not self.stages:
            raise ValueError("[[stages]]: give at least one stage")
        if any(c.viscosity is not None for c in sets):
            indirect = [f"stage '{s.name or i + 1}' has control = '{s.control}'"
                        for i, s in enumerate(self.stages or []) if s.control != "load"]
            if self.loading is not None and self.loading.control is not Control.displacement:
                indirect.append(f"[loading] has control = '{self.loading.control.value}'")
            if indirect:
                raise ValueError("[cohesive] viscosity relaxes over the pseudo-time of load-controlled steps; "
                                 f"{'; '.join(indirect)} (use control = 'load', or no viscosity)")
            if self.solver.fallback != "none":
                raise ValueError("[cohesive] viscosity and [solver] fallback = 'implex' are two regularisations "
                                 "of the same steps: give one of them")
        names = [s.name for s in self.stages or [] if s.name is not None]
        if len(set(names)) != len(names):
            raise ValueError(f"[[stages]]: stage names must differ (got {names})")
        monitors = [m.name for m in self.monitors or []]
        if len(set(monitors)) != len(monitors):
            raise ValueError(f"[[monitors]]: monitor names must differ (got {monitors})")
        return self

    @property
    def stage_sections(self) -> list[StageSection]:
        """The loading program as stages (the [loading] short form is expanded at build time)."""
        return list(self.stages or [])

    def resolved(self) -> Case:
        """The mesh and material sections with every default filled in."""
        update: dict[str, Any] = {"mesh": self.mesh.resolved()}
        if self.bulk is not None:
            update["bulk"] = self.bulk.resolved()
        else:
            update["materials"] = [m.resolved() for m in self.materials or []]
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
    if not data:
        raise CaseError(f"{path}: empty; a case file has [bulk] (or [[materials]]) and a loading program "
                        "([[stages]] or [loading]), and usually [mesh]")
    mesh = data.get("mesh")
    if isinstance(mesh, dict) and isinstance(mesh.get("file"), str) and not Path(mesh["file"]).is_absolute():
        data["mesh"] = dict(mesh, file=str((Path(path).parent / mesh["file"]).resolve()))
    return parse_case(data, str(path))


class DriveCommon(_Section):
    """A law for the material-point driver: the EP form, so kn and kt are required."""

    law: str = Field(DEFAULT_LAW, description="the traction law")
    kn: Stiffness = Field(description="normal penalty stiffness [Pa/m]")
    kt: Stiffness = Field(description="tangential penalty stiffness [Pa/m]")


def _drive_section(name: str, parameters: type[_Section]) -> type[DriveCommon]:
    return type(f"Drive_{name}", (DriveCommon, parameters), {
        "__annotations__": {"law": Literal[name]}, "law": Field(name, description="the traction law"),
        "__module__": __name__})


DRIVE_SECTIONS = {name: _drive_section(name, law.Parameters) for name, law in LAWS.items()}
globals().update({cls.__name__: cls for cls in DRIVE_SECTIONS.values()})  # found by name: picklable
if TYPE_CHECKING:  # the union is made at run time from the registry
    DriveLaw = DriveCommon
else:
    DriveLaw = Annotated[
        Union[tuple(Annotated[cls, Tag(name)] for name, cls in DRIVE_SECTIONS.items())],  # noqa: UP007
        Discriminator(lambda v: (v.get("law", DEFAULT_LAW) if isinstance(v, dict) else getattr(v, "law", DEFAULT_LAW)),
                      custom_error_type="law", custom_error_message=f"law must be one of {sorted(LAWS)}"),
    ]


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
