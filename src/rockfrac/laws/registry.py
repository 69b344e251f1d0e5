"""The cohesive traction laws rockfrac knows: one line per law (see rockfrac.laws.traction_law)."""

from __future__ import annotations

from rockfrac.laws.bilinear import Bilinear
from rockfrac.laws.mohr_coulomb_surface import MohrCoulombSurface
from rockfrac.laws.traction_law import TractionLaw

LAWS: dict[str, type[TractionLaw]] = {law.name: law for law in (MohrCoulombSurface, Bilinear)}
DEFAULT = MohrCoulombSurface.name  # [cohesive] without a law key: the paper's


def law_class(name: str) -> type[TractionLaw]:
    """The law registered under ``name``; KeyError naming the known ones."""
    if name not in LAWS:
        raise KeyError(f"unknown traction law {name!r}; known: {', '.join(sorted(LAWS))}")
    return LAWS[name]
