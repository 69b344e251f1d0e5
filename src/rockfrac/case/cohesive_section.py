"""[cohesive] / [[cohesive]]: a traction law, its form (EP penalty or RP multipliers) and where the
surfaces go.

The keys every cohesive set has are in :class:`CohesiveCommon`; the law's own keys come from the
law plug-in (``law = "..."``, default the paper's "mohr_coulomb"), so a registered law appears here
with its parameters and nothing else to change. ``TractionLawSection`` and ``CohesiveSection`` are
the paper's law's (its keys at the top level of [cohesive], as in the paper's case files).
"""

from __future__ import annotations

from enum import Enum
from typing import TYPE_CHECKING, Annotated, Any, Literal, Union

from pydantic import Discriminator, Field, Tag, model_validator

from rockfrac.laws.mohr_coulomb_surface import MohrCoulombParameters, WorkRule
from rockfrac.laws.registry import DEFAULT, LAWS
from rockfrac.values import Angle
from rockfrac.values import Section as _Section
from rockfrac.values import Stiffness

TractionLawSection = MohrCoulombParameters  # the paper's law, Sect. 4.2
SMOOTHING_ANGLE = 0.2618  # [rad], 15 degrees: normals = 'smoothed' without smoothing_angle


class CohesiveForm(str, Enum):
    ep = "ep"
    rp = "rp"


class Placement(str, Enum):
    crack = "crack"
    between = "between"
    within = "within"
    curves = "curves"
    surfaces = "surfaces"
    boundaries = "boundaries"
    all = "all"


class CohesiveCommon(_Section):
    """The cohesive-surface form (EP penalty or RP multipliers) and where the surfaces go: the
    specimen's crack, between two regions (grain/matrix), on every internal edge (face in 3D) within
    a region, along named curves (2D) or surfaces (3D), or on every internal edge (face)."""

    law: str = Field(DEFAULT, description=f"the traction law: {', '.join(repr(k) for k in LAWS)}")
    form: CohesiveForm = Field(strict=False, description="'ep' (elasto-plastic, penalty kn, kt) or 'rp' "
                               "(rigid-plastic, augmented Lagrange multipliers)")
    where: Placement = Field(Placement.crack, strict=False, description="'crack' (the specimen's), 'between' (two "
                             "regions), 'within' (a region), 'curves' (named curves, 2D), 'surfaces' (named surfaces, 3D), "
                             "'boundaries' (between any two different regions: every grain boundary) or 'all'")
    regions: list[str] | None = Field(None, description="between: two regions (the first is the minus side); "
                                      "within: one region")
    curves: list[str] | None = Field(None, description="curves: names of curve groups (edge sets)")
    surfaces: list[str] | None = Field(None, description="surfaces: names of surface groups (face sets) of a 3D "
                                       "mesh")
    kn: Stiffness | None = Field(None, description="EP only: normal penalty stiffness [Pa/m]")
    kt: Stiffness | None = Field(None, description="EP only: tangential penalty stiffness [Pa/m]")
    augmentation: Stiffness | None = Field(None, description="RP only: augmentation r [Pa/m]")
    multipliers: Literal["unknowns", "nested"] | None = Field(
        None, description="RP only: how the multipliers are solved: 'unknowns' (the paper's, with the "
        "displacements in one saddle-point Newton; the default) or 'nested' (held while Newton solves the "
        "displacements, then updated to the tractions until the rigid constraint is met: Uzawa, Simo & Laursen "
        "1992; no saddle point, a few updates a step where r is well above E / cell size)")
    integration: Literal["implicit", "implex"] = Field(
        "implicit", description="EP only: 'implicit' (the law's return at the end of each step) or 'implex' "
        "(Oliver et al. 2008: equilibrium with the plastic jump extrapolated from the last two steps; one "
        "Newton iteration per step, first order in the step size)")
    viscosity: float | None = Field(None, gt=0.0, le=1e6, description="EP (implicit) or RP: Duvaut-Lions "
                                    "relaxation time [pseudo-time of history.csv's 'time': one load-controlled "
                                    "stage = 1] of a viscous regularisation (Simo & Hughes 1998; for RP with "
                                    "the augmentation as stiffness), for load steps through snap-backs; its "
                                    "extra dissipation is the column D_viscous (default: none, the "
                                    "rate-independent law)")

    normals: Literal["pairs", "smoothed"] = Field(
        "pairs", description="each point's normal: 'pairs' (from the interface cells of its own node pair: "
        "the edge's or face's, the mean of both at a crack's kink; the paper's) or 'smoothed' (at each mesh node "
        "the set's points whose normals are within twice smoothing_angle of each other form a facet, whose "
        "points take its length- or area-weighted mean normal where all lie within smoothing_angle of it: a "
        "polygonal surface's vertex, each line of edges through a crossing; with surfaces on every edge "
        "the bulk's pairs tie a vertex's copies on each side, and rigid-plastic pairs there slide only "
        "along a frame they share)")
    points: Literal["nodes", "corners", "edges", "faces"] = Field(
        "nodes", description="where the integration points are: 'nodes' (one per node pair of the interface "
        "cells, the paper's nodal integration), 'corners' (the nodal rule cell by cell: a point at each corner "
        "of each interface cell, with the cell's normal and its own state; RP: one multiplier per cell, its "
        "mean jump rigid and each corner's deviation elastic with the augmentation as stiffness, so that with "
        "surfaces on every edge or face no ring of pairs round a node holds them shut; rockfrac.elements."
        "cse_corners), 'edges' (2D) or 'faces' (3D) (one per "
        "interface cell, its mean jump, and a moment k/2 (g - g_p)^T S (g - g_p) on the normal jumps g of its "
        "node pairs, the penalty's energy of their zero-mean part, k L (g_1 - g_0 - rho_p)^2 / 24 on an edge, "
        "its corner tractions capped at the point's tensile strength; k = kn or "
        "the augmentation: with surfaces on every edge or face, no ring of pairs round a node holds "
        "rigid-plastic surfaces shut; rockfrac.elements.cse_facets)")
    smoothing_angle: Angle | None = Field(
        None, gt=0.0, description="normals = 'smoothed': the largest angle [rad] between a point's normal and the "
        f"mean normal of its facet for the facet to be smoothed (default {SMOOTHING_ANGLE}: 15 degrees, a "
        "vertex of two edges at up to about 30 degrees)")

    @property
    def smoothing(self) -> float | None:
        """The smoothing angle of the set's normals [rad], None: each pair's own normal."""
        if self.normals == "pairs":
            return None
        return SMOOTHING_ANGLE if self.smoothing_angle is None else self.smoothing_angle

    @property
    def multiplier_unknowns(self) -> bool:
        """True if the set's multipliers are unknowns of the model (RP, not nested)."""
        return self.form is CohesiveForm.rp and self.multipliers != "nested"

    @model_validator(mode="after")
    def _placement(self) -> CohesiveCommon:
        need = {Placement.between: 2, Placement.within: 1}
        if self.where in need and (self.regions is None or len(self.regions) != need[self.where]):
            raise ValueError(f"where = '{self.where.value}' needs regions = a list of {need[self.where]} region name(s)")
        if self.where not in need and self.regions is not None:
            raise ValueError(f"regions only apply to where = 'between' or 'within', not '{self.where.value}'")
        if (self.where is Placement.curves) != (self.curves is not None):
            raise ValueError("curves go with where = 'curves' (a list of curve group names)")
        if (self.where is Placement.surfaces) != (self.surfaces is not None):
            raise ValueError("surfaces go with where = 'surfaces' (a list of surface group names of a 3D mesh)")
        if self.smoothing_angle is not None and self.normals != "smoothed":
            raise ValueError("smoothing_angle only applies to normals = 'smoothed'")
        if self.points != "nodes":
            clash = [f"{k} = {v!r}" for k, v in (("normals", self.normals), ("multipliers", self.multipliers),
                                                  ("integration", self.integration))
                     if v not in ("pairs", None, "unknowns", "implicit")]
            if clash:
                raise ValueError(f"points = {self.points!r} takes each cell's own normal, its multipliers as unknowns and "
                                 f"the implicit update (or viscosity), not {', '.join(clash)}")
        return self

    @model_validator(mode="after")
    def _form_keys(self) -> CohesiveCommon:
        if self.form is CohesiveForm.ep:
            missing = [k for k in ("kn", "kt") if getattr(self, k) is None]
            if missing:
                raise ValueError(f"form = 'ep' needs {', '.join(missing)} (penalty stiffness, Pa/m)")
            extra = [k for k in ("augmentation", "multipliers") if getattr(self, k) is not None]
            if extra:
                raise ValueError(f"{', '.join(extra)} only appl{'ies' if len(extra) == 1 else 'y'} to form = 'rp'")
            if self.viscosity is not None and self.integration != "implicit":
                raise ValueError("viscosity regularises the implicit update; integration = 'implex' is explicit "
                                 "already: give one of them")
        else:
            extra = [k for k in ("kn", "kt") if getattr(self, k) is not None]
            if extra:
                raise ValueError(f"{', '.join(extra)} only apply to form = 'ep' (RP has no elastic jump)")
            if self.integration != "implicit":
                raise ValueError("integration = 'implex' only applies to form = 'ep' (it extrapolates the "
                                 "plastic jump behind the penalty)")
        return self


def _section(name: str, parameters: type[_Section]) -> type[CohesiveCommon]:
    """[cohesive] with law = name: the common keys and the law's."""
    cls = type(f"Cohesive_{name}", (CohesiveCommon, parameters), {
        "__annotations__": {"law": Literal[name]},
        "law": Field(name, description="the traction law"),
        "__doc__": f"[cohesive] with law = '{name}': {LAWS[name].summary}",
        "__module__": __name__,
    })
    return cls


SECTIONS: dict[str, type[CohesiveCommon]] = {name: _section(name, law.Parameters) for name, law in LAWS.items()}
globals().update({cls.__name__: cls for cls in SECTIONS.values()})  # found by name: a case can be pickled
CohesiveSection = SECTIONS[DEFAULT]  # the paper's law's section


def _law_of(value: Any) -> str:
    if isinstance(value, dict):
        return value.get("law", DEFAULT) if isinstance(value.get("law", DEFAULT), str) else DEFAULT
    return getattr(value, "law", DEFAULT)


if TYPE_CHECKING:  # the union is made at run time from the registry
    AnyCohesiveSection = CohesiveCommon
else:
    AnyCohesiveSection = Annotated[
        Union[tuple(Annotated[cls, Tag(name)] for name, cls in SECTIONS.items())],  # noqa: UP007
        Discriminator(_law_of, custom_error_type="law",
                      custom_error_message=f"law must be one of {sorted(LAWS)}"),
    ]

__all__ = ["AnyCohesiveSection", "CohesiveCommon", "CohesiveForm", "CohesiveSection", "Placement", "SECTIONS",
           "TractionLawSection", "WorkRule"]
