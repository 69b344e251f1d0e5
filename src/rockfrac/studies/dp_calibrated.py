"""Calibrated Drucker-Prager parameters of the EDE bulk (paper Sect. 7, "Gosford sandstone").

Written by scripts/calibrate_dp.py (its docstring has the procedure); rerun it, do not edit.
beta and kappa0: plane-strain Mohr-Coulomb match of Table 1's (phi_p, c_p). b (dilatancy angle
19.1043 deg): puts the onset band at the angle where eq. (28) gives c_p = 9053 Pa
at 3700 N/m. H: root-found so that det A = 0 at 3700 N/m (W = 0.04 m, 20 kPa confinement, plane
strain). Result: first yield 2691.56 N/m, onset 3700.00 N/m, bands at +-56.4065 deg.
"""

from rockfrac.laws.drucker_prager_params import DruckerPrager

# E, kappa0, H [Pa]; nu, beta, b [-]
PARAMETERS = {
    "E": 15000000.0,
    "nu": 0.3,
    "beta": 0.480385,
    "b": 0.321597,
    "kappa0": 7532.54,
    "H": 43802.9,
}


def calibrated() -> DruckerPrager:
    """The calibrated law."""
    return DruckerPrager(**PARAMETERS)
