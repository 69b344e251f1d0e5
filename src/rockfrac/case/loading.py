"""[loading]: the paper's short loading program (confinement, then axial shortening)."""

from __future__ import annotations

from enum import Enum

from pydantic import Field, model_validator

from rockfrac.values import Count, Displacement, Fraction, Length, Strength
from rockfrac.values import Section as _Section


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
