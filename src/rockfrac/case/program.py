"""[[stages]], [initial] and [[monitors]]: a loading program on named groups, the state at t = 0,
and the quantities to follow.

A stage gives the values its loads reach at its end; every load ramps linearly with the stage's
load factor from its value at the start of the stage, and whatever a stage does not name keeps
its value (held). A prescribed displacement component stays prescribed in later stages until a
stage sets it "free". Units: m, Pa, m/s^2; tension positive; a pressure pushes on its boundary.
"""

from __future__ import annotations

from typing import Literal

from pydantic import Field, model_validator

from rockfrac.values import (
    MAX_STRESS,
    Coordinate,
    Count,
    Displacement,
    Fraction,
    Length,
    Stress,
)
from rockfrac.values import Section as _Section

Component = Literal["x", "y", "z"]
GroupName = str
Acceleration = float  # bounded below
MAX_ACCELERATION = 1e4  # [m/s^2], a thousand g
MAX_FACTOR = 1e3


def _check_names(names, what: str) -> None:
    for n in names:
        if not n or len(n) > 200 or any(c in n for c in "\n\r\x00"):
            raise ValueError(f"{what} {n!r}: a group name is 1-200 characters, one line")


class StopSection(_Section):
    """End the program when a history quantity falls below a fraction of its peak magnitude."""

    quantity: str = Field(min_length=1, max_length=200, description="a history column, e.g. 'R_top_y' or a "
                          "monitor's name")
    below_peak_fraction: Fraction = Field(description="stop once |quantity| < this x its peak |quantity|")


class StageSection(_Section):
    """One stage of the loading program: end values of its loads, its control and steps."""

    name: str | None = Field(None, min_length=1, max_length=100, description="the stage's name (default "
                             "'stage N')")
    steps: Count = Field(1, description="load-controlled steps (the nominal increment is 1/steps of the stage)")
    control: Literal["load", "path", "opening", "arc_length", "energy"] = Field(
        "load", description="'load': the load factor is prescribed; 'path': once a crack yields, each step "
        "prescribes an increment of its mean opening; 'opening': each step prescribes an increment of the opening "
        "monitor named by 'monitor' (e.g. a CMOD); 'arc_length': each step prescribes an increment of the "
        "displacement along the last step's direction (the first step is load-controlled); 'energy': once a crack "
        "yields (or a load step fails at a limit point), each step prescribes the energy released (force-driven "
        "stages on supports held at 0); in all but 'load' the load factor is solved for, so it may fall after a "
        "peak and rise again")
    monitor: str | None = Field(None, min_length=1, max_length=100, description="control = 'opening': the name "
                                "of the [[monitors]] opening it prescribes")
    path_increment: Length | None = Field(None, description="increment per step [m] of the crack opening "
                                          "(path; default from the stage's displacements), the monitor's "
                                          "opening (opening) or the root-mean-square nodal displacement along "
                                          "the path (arc_length); default for these two: its change over a "
                                          "nominal load step, from the first step; the energy released per step "
                                          "(energy) [J/m per unit thickness in 2D, J in 3D], needed")
    max_steps: Count | None = Field(None, description="path, opening, arc_length or energy control: most steps "
                                    "of the stage (default 20 x steps)")
    displacement: dict[GroupName, dict[Component, Displacement | Literal["free"]]] = Field(
        default_factory=dict, description="node group -> component -> prescribed value at the stage end [m], "
        "or 'free' to release it")
    pressure: dict[GroupName, Stress] = Field(default_factory=dict, description="boundary group -> normal "
                                              "pressure at the stage end [Pa] (positive pushes inward)")
    traction: dict[GroupName, list[Stress]] = Field(default_factory=dict, description="boundary group -> "
                                                    "traction vector at the stage end [Pa], global frame")
    gravity: list[float] | None = Field(None, description="gravitational acceleration at the stage end "
                                        "[m/s^2] (body force density x g on every region with a density)")
    in_situ: dict[GroupName, float] = Field(default_factory=dict, description="boundary group -> factor on the "
                                            "in-situ traction sigma0 . n at the stage end (1 at t = 0; 0 "
                                            "excavates)")
    stop: StopSection | None = Field(None, description="end the program when a quantity softens below a "
                                     "fraction of its peak")

    @model_validator(mode="after")
    def _consistent(self) -> StageSection:
        _check_names(list(self.displacement) + list(self.pressure) + list(self.traction) + list(self.in_situ),
                     "group")
        for name, comps in self.displacement.items():
            if not comps:
                raise ValueError(f"displacement.{name}: give at least one component (x, y, z)")
        for name, t in self.traction.items():
            if len(t) not in (2, 3):
                raise ValueError(f"traction.{name}: a vector of 2 (2D) or 3 (3D) components [Pa]")
        both = sorted(set(self.pressure) & set(self.traction))
        if both:
            raise ValueError(f"{', '.join(both)}: a group takes a pressure or a traction in one stage, not both")
        if self.gravity is not None:
            if len(self.gravity) not in (2, 3) or any(abs(g) > MAX_ACCELERATION for g in self.gravity):
                raise ValueError(f"gravity: a vector of 2 or 3 components, each at most {MAX_ACCELERATION:g} m/s^2")
        for name, f in self.in_situ.items():
            if not 0.0 <= f <= MAX_FACTOR:
                raise ValueError(f"in_situ.{name}: a factor from 0 to {MAX_FACTOR:g} (got {f:g})")
        if self.control == "load":
            given = [k for k in ("path_increment", "max_steps") if getattr(self, k) is not None]
            if given:
                raise ValueError(f"{', '.join(given)} only apply to control = 'path', 'opening', 'arc_length' or "
                                 "'energy'")
        if self.control == "energy" and self.path_increment is None:
            raise ValueError("path_increment: control = 'energy' needs the energy released per step [J/m in 2D (per "
                             "unit thickness), J in 3D]")
        if (self.control == "opening") != (self.monitor is not None):
            raise ValueError("control = 'opening' takes monitor = '<name of an opening monitor>'; monitor applies "
                             "to no other control")
        return self


class InitialStressSection(_Section):
    """An in-situ stress field in some regions, uniform or varying linearly with elevation:
    sigma0(e) = stress + (e - datum) gradient, e = y in 2D (z in 3D). Voigt order (xx, yy, zz, xy[, yz, xz])
    [Pa], tension positive (compression negative)."""

    regions: list[str] | None = Field(None, description="the regions it fills (default: every region)")
    stress: list[Stress] = Field(description="sigma0 at the datum [Pa]: sxx, syy, szz, sxy (2D) or all six")
    gradient: list[Stress] | None = Field(None, description="d sigma0 / d elevation [Pa/m], same components "
                                          "(default 0)")
    datum: Coordinate = Field(0.0, description="elevation where sigma0 = stress [m]")

    @model_validator(mode="after")
    def _components(self) -> InitialStressSection:
        if len(self.stress) not in (4, 6):
            raise ValueError("stress: 4 components (sxx, syy, szz, sxy) or 6 (sxx, syy, szz, sxy, syz, sxz)")
        if self.gradient is not None and len(self.gradient) != len(self.stress):
            raise ValueError(f"gradient: as many components as stress ({len(self.stress)})")
        if self.regions is not None:
            _check_names(self.regions, "region")
        return self


class InitialSection(_Section):
    """The state at t = 0: gravity and the in-situ stress, in equilibrium with the boundary tractions
    sigma0 . n (applied on every outer boundary, held until a stage changes their in_situ factor)."""

    gravity: list[float] | None = Field(None, description="gravitational acceleration at t = 0 [m/s^2]")
    stress: list[InitialStressSection] = Field(default_factory=list, description="in-situ stress fields, "
                                               "one per set of regions")

    @model_validator(mode="after")
    def _gravity(self) -> InitialSection:
        if self.gravity is not None and (len(self.gravity) not in (2, 3)
                                         or any(abs(g) > MAX_ACCELERATION for g in self.gravity)):
            raise ValueError(f"gravity: a vector of 2 or 3 components, each at most {MAX_ACCELERATION:g} m/s^2")
        return self


class MonitorSection(_Section):
    """A quantity to follow in history.csv.

    displacement: the displacement of the node nearest ``at`` (columns <name>_x, <name>_y[, _z]).
    opening: the relative displacement of the second point (or group mean) against the first along
    the unit vector from the first to the second (a crack mouth opening; column <name>); with
    groups, along ``direction``. A point on a cohesive crack has two nodes there (one per face)
    and takes the first: put gauge points off the crack, on either side.
    """

    name: str = Field(min_length=1, max_length=100, pattern=r"^[A-Za-z][A-Za-z0-9_]*$",
                      description="column name (letters, digits, underscores)")
    kind: Literal["displacement", "opening"] = Field(description="'displacement' or 'opening'")
    at: list[Coordinate] | None = Field(None, description="displacement: the point [m]")
    points: list[list[Coordinate]] | None = Field(None, description="opening: two points [m]")
    groups: list[str] | None = Field(None, description="opening: two node groups (their mean displacements)")
    direction: list[float] | None = Field(None, description="opening with groups: the direction to measure "
                                          "along (normalised)")

    @model_validator(mode="after")
    def _kind(self) -> MonitorSection:
        if self.kind == "displacement":
            if self.at is None or len(self.at) not in (2, 3) or self.points or self.groups or self.direction:
                raise ValueError("kind = 'displacement' takes at = [x, y] (or [x, y, z]) and nothing else")
            return self
        if self.at is not None:
            raise ValueError("kind = 'opening' takes points = [[x1, y1], [x2, y2]] or groups = [g1, g2], not at")
        if (self.points is None) == (self.groups is None):
            raise ValueError("kind = 'opening' takes either points = [[x1, y1], [x2, y2]] or groups = [g1, g2]")
        if self.points is not None:
            if len(self.points) != 2 or any(len(p) not in (2, 3) for p in self.points):
                raise ValueError("points: two points [[x1, y1], [x2, y2]]")
            if self.points[0] == self.points[1]:
                raise ValueError("points: two different points (the opening is measured from the first "
                                 "to the second)")
            if self.direction is not None:
                raise ValueError("direction goes with groups (with points, it is from the first to the second)")
        elif self.groups is not None:
            if len(self.groups) != 2:
                raise ValueError("groups: two node groups")
            if self.direction is None or len(self.direction) not in (2, 3) or not any(self.direction) or \
                    any(abs(d) > MAX_STRESS for d in self.direction):
                raise ValueError("groups need direction = [dx, dy] (a nonzero vector)")
        return self
