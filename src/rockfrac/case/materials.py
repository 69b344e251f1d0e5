"""[bulk], [[materials]] and [embedded]: the bulk laws and the embedded discontinuities."""

from __future__ import annotations

import math
from enum import Enum
from typing import Annotated, Literal

from pydantic import Field, model_validator

from rockfrac.values import (
    Angle,
    Coefficient,
    Coordinate,
    Count,
    Hardening,
    Length,
    Modulus,
    Rate,
    Stiffness,
    Strength,
)
from rockfrac.values import Section as _Section


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
    density: float | None = Field(None, ge=0, le=1e5, description="mass density [kg/m^3] (needed with gravity)")

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

        DruckerPrager(self.E, self.nu, float(self.beta or 0.0), float(self.b or 0.0), float(self.kappa0 or 0.0),
                      self.H or 0.0)  # admissible? (ValueError)
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


class EmbeddedCrackSection(_Section):
    """A crack present from the start (a joint or fault) in the embedded-discontinuity continuum: in 2D
    a polyline, every cell it crosses cut along its chord; in a general 3D body a plane, every cell it
    crosses cut by it."""

    points: list[list[Coordinate]] | None = Field(None, min_length=2, max_length=10_000,
                                                  description="2D: the polyline's points [[x, y], ...] [m]")
    point: list[Coordinate] | None = Field(None, min_length=3, max_length=3,
                                           description="3D: a point [x, y, z] of the plane [m]")
    normal: list[Annotated[float, Field(ge=-1e3, le=1e3)]] | None = Field(
        None, min_length=3, max_length=3, description="3D: the plane's normal [nx, ny, nz] (any length but 0)")
    c_p: Strength = Field(description="peak cohesion of its surfaces [Pa] (they soften by the [embedded] law)")

    @model_validator(mode="after")
    def _polyline(self) -> EmbeddedCrackSection:
        plane = self.point is not None or self.normal is not None
        if (self.points is None) == (not plane) or (plane and (self.point is None or self.normal is None)):
            raise ValueError("a crack is either points = [[x, y], ...] (2D) or point = [x, y, z] with "
                             "normal = [nx, ny, nz] (3D)")
        if self.points is not None:
            if any(len(p) != 2 for p in self.points):
                raise ValueError("points must be [x, y] pairs")
            if any(p == q for p, q in zip(self.points[:-1], self.points[1:])):
                raise ValueError("points: two consecutive points are the same")
        elif not math.hypot(*(self.normal or [0.0])) > 1e-9:
            raise ValueError("normal must not be zero")
        return self


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
    tracking: Literal["none", "local", "nonlocal"] = Field(
        "none", description="'none': each cell's surface through its centroid (the paper's Tahoe element); "
        "'local': a cell next to a cut cell continues that cell's surface (a continuous crack path) with "
        "the normal of its own stress; 'nonlocal': with the normal of the stress averaged around the tip "
        "over tracking_length (Wells & Sluys 2001)")
    tracking_length: Length | None = Field(
        None, description="tracking = 'nonlocal': Gaussian length [m] of the stress average at a crack tip "
        "(a few cell sizes)")
    regions: list[str] | None = Field(None, description="regions that may localize (default: every "
                                      "drucker_prager region)")
    cracks: list[EmbeddedCrackSection] = Field(default_factory=list, max_length=10_000, description=(
        "cracks present from the start: [[embedded.cracks]] points = [[x, y], ...], c_p = ... (2D), or "
        "point = [x, y, z], normal = [nx, ny, nz], c_p = ... (a plane, 3D)"))
    max_cracks: Count = Field(1, description="tracking 'local' or 'nonlocal': most cracks started (those "
                            "of cracks included); further cuts continue them from their tips")
    kinematics: Literal["elemental", "nodal"] = Field(
        "elemental", description="'elemental': one constant jump per cut cell, condensed in it (the paper's "
        "AES element); 'nodal': the cut cell's two sides deform on their own and the jump is a nodal field, "
        "continuous along the crack (shifted Heaviside enrichment; no stress locking across a slanted band; "
        "2D, tracking 'local' or 'nonlocal', needs kn and kt)")
    kn: Stiffness | None = Field(None, description="kinematics = 'nodal': normal penalty stiffness of the crack [Pa/m]")
    kt: Stiffness | None = Field(None, description="kinematics = 'nodal': tangential penalty stiffness of the crack "
                                 "[Pa/m]")

    @model_validator(mode="after")
    def _residual_below_peak(self) -> EmbeddedSection:
        if self.tracking == "nonlocal" and self.tracking_length is None:
            raise ValueError("tracking = 'nonlocal' needs tracking_length [m] (the Gaussian length of the "
                             "stress average at a crack tip)")
        if self.tracking != "nonlocal" and self.tracking_length is not None:
            raise ValueError(f"tracking_length only applies to tracking = 'nonlocal' (tracking is '{self.tracking}')")
        if self.phi_r > self.phi_p or (self.c_p != "eq28" and self.c_r > self.c_p):
            raise ValueError("residual values (c_r, phi_r) must not exceed the peak ones")
        if self.c_p != "eq28" and self.c_p <= 0:
            raise ValueError("c_p must be > 0 or 'eq28'")
        if self.kinematics == "nodal":
            if self.kn is None or self.kt is None:
                raise ValueError("kinematics = 'nodal' needs the crack's penalty stiffnesses kn and kt [Pa/m]")
            if self.tracking == "none":
                raise ValueError("kinematics = 'nodal' needs a continuous crack path: tracking = 'local' or "
                                 "'nonlocal' (with tracking = 'none' each cell is cut on its own)")
        elif self.kn is not None or self.kt is not None:
            raise ValueError("kn and kt are the penalty of kinematics = 'nodal' (the elemental jump is rigid-plastic)")
        return self
