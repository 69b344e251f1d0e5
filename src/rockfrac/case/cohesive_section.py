"""[cohesive] / [[cohesive]]: the traction law of Sect. 4.2, its form and where the surfaces go."""

from __future__ import annotations

from enum import Enum

from pydantic import Field, model_validator

from rockfrac.case.types import Angle, Energy, Rate, Stiffness, Strength
from rockfrac.case.types import Section as _Section


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
