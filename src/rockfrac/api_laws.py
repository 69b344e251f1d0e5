"""The laws in the Python API: a traction law with its parameters, and the loss of ellipticity of
Drucker-Prager at a stress state, with the same validation as the input files.

    import rockfrac as rf

    lw = rf.law("bilinear", sigma_c=2e6, Gc=100.0, kn=1e13, kt=1e13)
    path = lw.drive(jumps)          # the material-point driver: jumps (n, 2) [t, n] in m
    loc = rf.localization(E=1.5e7, nu=0.3, beta=0.5, b=0.35, kappa0=1.3e4, stress=[...])
"""

from __future__ import annotations

from typing import Any

import numpy as np
from pydantic import ValidationError

from rockfrac.case.messages import format_errors
from rockfrac.errors import CaseError
from rockfrac.laws.bifurcation import Localization, localization_at
from rockfrac.laws.drucker_prager_params import DruckerPrager
from rockfrac.laws.registry import law_class
from rockfrac.laws.traction_law import TractionLaw


def law(name: str, *, kn: float | None = None, kt: float | None = None, **parameters: Any) -> TractionLaw:
    """The traction law ``name`` with its parameters (validated as in a [cohesive] section): the EP
    form with kn, kt [Pa/m], the RP form without."""
    try:
        cls = law_class(name)
    except KeyError as err:
        raise CaseError(f"<python law>: law: {err.args[0]}") from None
    try:
        params = cls.Parameters.model_validate(parameters)
    except ValidationError as err:
        raise CaseError(format_errors("<python law>", err, cls.Parameters)) from None
    if (kn is None) != (kt is None):
        raise CaseError("<python law>: give both kn and kt (the EP form) or neither (the RP form)")
    return cls(params, kn=kn, kt=kt)


def localization(*, E: float, nu: float, beta: float, b: float, kappa0: float, stress, H: float = 0.0,
                 plane_strain: bool = True) -> Localization:
    """Minima of det A(n) / det A^e(n) (paper eq. 7-8) of Drucker-Prager at a Voigt stress (6,)
    [Pa] (xx, yy, zz, xy, yz, xz), tension positive."""
    try:
        dp = DruckerPrager(E, nu, beta, b, kappa0, H)
    except ValueError as err:
        raise CaseError(f"<python law>: {err}") from None
    sigma = np.asarray(stress, dtype=float)
    if sigma.shape != (6,) or not np.all(np.isfinite(sigma)):
        raise CaseError("<python law>: stress: six finite components (xx, yy, zz, xy, yz, xz) [Pa]")
    return localization_at(dp, sigma, plane_strain=plane_strain)
