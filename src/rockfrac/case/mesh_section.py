"""[mesh]: the paper's specimen, a Gmsh file, a generated grain specimen or a block."""

from __future__ import annotations

import math
from enum import Enum

from pydantic import Field, model_validator

from rockfrac.values import Coordinate, Count, Length
from rockfrac.values import Section as _Section

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
    tet4 = "tet4"

    @property
    def solid(self) -> bool:
        """A 3D cell (a block of thickness T, nz cells through it)."""
        return self in (ElementType.hex8, ElementType.tet4)


MESH_KEYS = {  # keys of [mesh] beyond kind, element, width, height, per kind
    MeshKind.specimen: {"crack", "crack_angle", "nx", "ny", "thickness", "nz"},
    MeshKind.gmsh: {"file"},
    MeshKind.grains: {"n_grains", "radius_min", "radius_max", "seed", "element_size", "points_per_circle"},
    MeshKind.block: {"nx", "ny", "inclusion", "thickness", "nz"},
}
OPTIONAL_MESH_KEYS = set().union(*MESH_KEYS.values())


class MeshSection(_Section):
    """The mesh: the paper's specimen, a Gmsh file, a generated grain specimen or a block.

    specimen: a W x H plane-strain block (PAPER_NOTES, Sect. 7); element = "quad4": two blocks of
    nx x ny quads cut by a crack through the centre at crack_angle (or one block, crack = false);
    "hex8": nx x ny x nz hexahedra of thickness T, both out-of-plane faces held, no crack.
    gmsh: a .msh file (2D: tri3 or quad4; 3D, in general 3D: tet4 or hex8); physical groups name
    regions and boundaries (in 3D, physical surfaces the faces loads act on).
    grains: n_grains circular stiff grains in a matrix (regions "grains", "matrix"), made by Gmsh.
    block: a W x H nx x ny grid, with an optional weak inclusion box (regions "weak", "bulk"); element =
    "hex8": nx x ny x nz hexahedra of thickness T (z), a general 3D body (the inclusion through the thickness);
    "tet4": the same grid, each hexahedron split into six tetrahedra around its diagonal.
    Every kind provides the boundary groups bottom, top, left, right and bottom_left.
    """

    kind: MeshKind = Field(MeshKind.specimen, strict=False, description="'specimen', 'gmsh', 'grains' or 'block'")
    element: ElementType = Field(ElementType.quad4, strict=False, description="'tri3', 'quad4' (2D), 'hex8' (3D: plane strain in the specimen, general in a block) or 'tet4' (a block)")
    width: Length = Field(0.04, description="specimen width W [m]")
    height: Length = Field(0.08, description="specimen height H [m]")
    thickness: Length | None = Field(None, description="hex8, tet4 only: thickness T [m] (default 0.08)")
    crack: bool | None = Field(None, description="specimen, quad4: cut the specimen with a crack (default true)")
    crack_angle: float | None = Field(
        None, gt=-math.pi / 2, lt=math.pi / 2, description="crack angle from horizontal [rad] (default 60 deg)"
    )
    nx: Count | None = Field(None, le=MAX_CELLS_ALONG, description="elements across (in each block when cracked) (default 1)")
    ny: Count | None = Field(None, le=MAX_CELLS_ALONG, description="element layers (in each block when cracked) (default 1)")
    nz: Count | None = Field(None, le=MAX_CELLS_ALONG, description="hex8, tet4 only: elements through the thickness (default 1)")
    file: str | None = Field(None, description="gmsh: the .msh file (relative to the case file)")
    n_grains: Count | None = Field(None, le=100_000, description="grains: number of grains (default 60)")
    radius_min: Length | None = Field(None, description="grains: smallest grain radius [m] (default W/25)")
    radius_max: Length | None = Field(None, description="grains: largest grain radius [m] (default W/12)")
    seed: int | None = Field(None, ge=0, le=2**32 - 1, description="grains: random seed of the placement (default 0)")
    element_size: Length | None = Field(None, description="grains: the largest element [m] (default W/40)")
    points_per_circle: Count | None = Field(None, ge=8, le=10_000, description="grains: nodes at least on each grain's "
                                            "circle (default 24; near the grains this, not element_size, sets the "
                                            "elements' size: refine both together)")
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
        if self.element is ElementType.hex8 and self.kind not in (MeshKind.specimen, MeshKind.block):
            raise ValueError("element = 'hex8' is for kind = 'specimen' or 'block' (a gmsh file brings its own cells)")
        if self.element is ElementType.tet4 and self.kind is not MeshKind.block:
            raise ValueError("element = 'tet4' is for kind = 'block' (a gmsh file brings its own cells)")
        if self.element.solid:
            if self.crack:
                raise ValueError("element = 'hex8' cannot carry a cohesive crack (CSEs are 2D): use "
                                 "element = 'quad4' or crack = false")
            if self.crack_angle is not None:
                raise ValueError("crack_angle only applies to element = 'quad4' with a crack")
        else:
            given = [k for k in ("thickness", "nz") if getattr(self, k) is not None]
            if given:
                raise ValueError(f"{', '.join(given)} only apply to element = 'hex8' or 'tet4'")
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
                                           "element_size": self.element_size or w / 40,
                                           "points_per_circle": self.points_per_circle or 24})
        if k is MeshKind.block and self.element.solid:
            return self.model_copy(update={"nx": self.nx or 1, "ny": self.ny or 1, "nz": self.nz or 1,
                                           "thickness": self.thickness or 0.08})
        if k is MeshKind.block:
            return self.model_copy(update={"nx": self.nx or 1, "ny": self.ny or 1})
        return self

    @property
    def has_crack(self) -> bool:
        """The specimen's own crack (the cohesive sets of other meshes are placed by [cohesive])."""
        return bool(self.resolved().crack)
