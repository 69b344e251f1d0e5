"""Value types of the input schemas: finite, strict and bounded.

Every number a case, law or material file gives reaches a compiled kernel, so each is checked here
before anything runs: no ``nan`` or ``inf`` (``allow_inf_nan=False``), no booleans or strings where
a number goes and no floats where an integer goes (``strict=True``), and magnitudes bounded well
inside what the kernels can square and sum without overflow (a modulus of 1e300 Pa would make
``inf`` stiffnesses, a count of 1e12 steps or cells would exhaust memory). The bounds are far
beyond rock (diamond's modulus is 1.2e12 Pa), so no real problem meets them.
"""

from __future__ import annotations

import math
from typing import Annotated, TypeVar

from pydantic import BaseModel, ConfigDict, Field

T = TypeVar("T")

MAX_MODULUS = 1e13  # Young's moduli [Pa]
MAX_STRESS = 1e11  # strengths, pressures, stresses [Pa]
MAX_STIFFNESS = 1e20  # penalty stiffnesses and augmentations [Pa/m]
MIN_LENGTH, MAX_LENGTH = 1e-9, 1e5  # sizes [m]
MAX_DISPLACEMENT = 1e3  # prescribed displacements [m]
MAX_ENERGY = 1e9  # fracture energies [J/m^2]
MAX_RATE = 1e12  # softening rates [-] or [1/m]
MAX_COUNT = 10_000_000  # steps, iterations, elements along a side

Modulus = Annotated[float, Field(gt=0, le=MAX_MODULUS)]
Hardening = Annotated[float, Field(ge=-MAX_MODULUS, le=MAX_MODULUS)]
Stress = Annotated[float, Field(ge=-MAX_STRESS, le=MAX_STRESS)]
Strength = Annotated[float, Field(ge=0, le=MAX_STRESS)]
Stiffness = Annotated[float, Field(gt=0, le=MAX_STIFFNESS)]
Length = Annotated[float, Field(ge=MIN_LENGTH, le=MAX_LENGTH)]
Coordinate = Annotated[float, Field(ge=-MAX_LENGTH, le=MAX_LENGTH)]
Displacement = Annotated[float, Field(ge=-MAX_DISPLACEMENT, le=MAX_DISPLACEMENT)]
Energy = Annotated[float, Field(gt=0, le=MAX_ENERGY)]
Rate = Annotated[float, Field(ge=0, le=MAX_RATE)]
Angle = Annotated[float, Field(ge=0, lt=math.pi / 2)]  # friction and dilation angles [rad]
Count = Annotated[int, Field(ge=1, le=MAX_COUNT)]
Coefficient = Annotated[float, Field(ge=0, le=1e3)]  # dimensionless friction-like coefficients
Fraction = Annotated[float, Field(gt=0, lt=1)]


class Section(BaseModel):
    """A section of an input file: unknown keys refused, values strict and finite, immutable.

    Enum-valued keys are declared with ``strict=False`` on their field (a TOML string names the
    member); every other value must have the declared type exactly (an int is taken as a float).
    """

    model_config = ConfigDict(extra="forbid", frozen=True, strict=True, allow_inf_nan=False)


def given(value: T | None, key: str = "value") -> T:
    """A value the schema guarantees once the case is resolved (every default filled in)."""
    if value is None:
        raise AssertionError(f"{key} was not resolved")
    return value
