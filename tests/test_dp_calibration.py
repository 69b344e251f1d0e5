"""Material-point driver of the specimen (elastic closed form, Newton) and the calibrated parameters."""

import math
import runpy
import tomllib
from pathlib import Path

import numpy as np
import pytest

from rockfrac.laws.bifurcation import peak_cohesion
from rockfrac.laws.dp_driver import drive_specimen, elastic_stress, elastic_yield_force
from rockfrac.laws.drucker_prager_params import DruckerPrager, mohr_coulomb_beta, mohr_coulomb_kappa
from rockfrac.studies.dp_calibrated import PARAMETERS, calibrated

ROOT = Path(__file__).resolve().parents[1]
P, W, F_B, PHI_P, C_P = 2.0e4, 0.04, 3700.0, 0.5236, 9053.0


@pytest.fixture(scope="module")
def calibrated_path():
    return drive_specimen(calibrated(), confinement=P, axial_strain=-0.02, steps=400, width=W)


def test_elastic_part_matches_the_plane_strain_closed_form():
    lw = DruckerPrager(E=1.5e7, nu=0.3, beta=0.4, b=0.1, kappa0=1e7, H=0.0)  # never yields here
    path = drive_specimen(lw, confinement=P, axial_strain=-5e-3, steps=10, confinement_steps=2)
    assert np.all(path.mode == 0) and np.all(path.det_ratio == 1.0)
    E, nu = lw.E, lw.nu
    # confinement with eps_yy = 0: sigma_yy = sigma_zz = -p nu/(1 - nu)
    assert path.sigma[2] == pytest.approx([-P, -P * nu / (1 - nu), -P * nu / (1 - nu), 0, 0, 0], rel=1e-10)
    assert path.sigma[1, 0] == pytest.approx(-P / 2, rel=1e-10)
    for k in range(3, path.eps_yy.size):
        ref = elastic_stress(lw, P, path.eps_yy[k])
        assert path.sigma[k] == pytest.approx(ref, rel=1e-10, abs=1e-6)
        # eps_xx = [(1 - nu^2) sigma_xx - nu (1 + nu) sigma_yy] / E
        assert path.eps_xx[k] == pytest.approx(((1 - nu**2) * ref[0] - nu * (1 + nu) * ref[1]) / E, rel=1e-10)
    u = -path.eps_yy[-1] * 0.08  # force-shortening line of rockfrac.analytic, H = 0.08 m
    assert path.force[-1] == pytest.approx(W * (E / (1 - nu**2) * u / 0.08 + nu / (1 - nu) * P), rel=1e-10)


def test_newton_on_the_lateral_stress_converges_fast(calibrated_path):
    path = calibrated_path
    assert np.all(np.abs(path.sigma[1:, 0] + P) < 1e-6)
    plastic = path.mode == 1
    assert plastic.sum() > 50
    assert path.iterations[plastic].max() <= 4  # quadratic with the consistent tangent


def test_associative_plane_strain_limit_is_the_matched_mohr_coulomb():
    """b = beta, H = 0: the plane-strain path tends to the Mohr-Coulomb surface of the match."""
    phi, c = math.radians(30.0), 1.0e4
    lw = DruckerPrager(E=1.5e7, nu=0.3, beta=mohr_coulomb_beta(phi), b=mohr_coulomb_beta(phi),
                       kappa0=mohr_coulomb_kappa(phi, c), H=0.0)
    path = drive_specimen(lw, confinement=P, axial_strain=-0.3, steps=300)
    sxx, syy = path.sigma[-1, 0], path.sigma[-1, 1]
    radius, centre = 0.5 * (sxx - syy), 0.5 * (sxx + syy)
    assert radius == pytest.approx(c * math.cos(phi) - centre * math.sin(phi), rel=1e-3)


def test_calibrated_parameters_reproduce_the_paper(calibrated_path):
    lw = calibrated()
    assert lw.H > 0 and 0 < lw.b < lw.beta
    assert lw.beta == pytest.approx(mohr_coulomb_beta(PHI_P), rel=1e-5)
    assert lw.kappa0 == pytest.approx(mohr_coulomb_kappa(PHI_P, C_P), rel=1e-5)
    path = calibrated_path
    o = path.onset
    assert o is not None
    assert o.force == pytest.approx(F_B, rel=0.01)
    ang = o.localization.band_angles_deg
    assert np.all((np.abs(ang) >= 55.0) & (np.abs(ang) <= 65.0)) and ang[0] == pytest.approx(-ang[1], abs=1e-8)
    # yields, then hardens (the force rises) until the onset
    f_y = elastic_yield_force(lw, P, W)
    k_y = path.first_yield
    assert path.force[k_y - 1] < f_y <= path.force[k_y] and f_y < 0.8 * F_B
    rising = path.force[k_y:o.step + 1]
    assert np.all(np.diff(rising) > 0)
    assert np.all(path.det_ratio[k_y:o.step] > 0) and path.det_ratio[o.step] <= 0
    # eq. (28): the Mohr-Coulomb traction of the onset stress on the band plane. The band angle was
    # calibrated to the plane where the paper's numbers satisfy (28), so this is a consistency check
    c_p = peak_cohesion(o.sigma, o.localization.normals[0], math.tan(PHI_P))
    assert c_p == pytest.approx(C_P, rel=0.01)
    c_n = peak_cohesion(path.sigma[o.step - 1], o.localization.normals[0], math.tan(PHI_P))
    assert c_n == pytest.approx(C_P, rel=0.01) and c_n < c_p


def test_onset_does_not_depend_on_the_step_size():
    lw = calibrated()
    f = [drive_specimen(lw, axial_strain=-0.02, steps=n, stop_at_onset=True).onset.force for n in (100, 400)]
    assert f[0] == pytest.approx(f[1], rel=2e-3)


def test_stored_files_agree():
    material = tomllib.loads((ROOT / "examples" / "laws" / "dp_calibrated.toml").read_text())["material"]
    assert material == PARAMETERS
    script = runpy.run_path(str(ROOT / "scripts" / "calibrate_dp.py"))  # not __main__: nothing runs
    theta = script["target_angle"]()
    assert script["plane_cohesion"](theta, F_B / W) == pytest.approx(C_P, rel=1e-12)
    assert math.degrees(theta) == pytest.approx(56.4065, abs=1e-4)
