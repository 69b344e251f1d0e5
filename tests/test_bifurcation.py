"""Loss of ellipticity (eq. 7-8): acoustic tensor, searches vs closed forms, slip, and the CLI."""

import math
from pathlib import Path

import numpy as np
import pytest

from rockfrac.cli import main
from rockfrac.studies import table1
from rockfrac.laws import bifurcation as bf
from rockfrac.laws import drucker_prager as dp
from rockfrac.laws.drucker_prager_params import DruckerPrager

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "laws" / "dp_calibrated.toml"
GOSFORD = ROOT / "examples" / "laws" / "dp_gosford.toml"
VOIGT = [(0, 0), (1, 1), (2, 2), (0, 1), (1, 2), (0, 2)]


def law(phi_deg=30.0, psi_deg=5.0, nu=0.3):
    return DruckerPrager.from_mohr_coulomb(1.5e7, nu, math.radians(phi_deg), 1e4, math.radians(psi_deg))


def voigt(t):
    return np.array([t[i, j] for i, j in VOIGT])


def rotated(sig_principal, R):
    return voigt(R @ np.diag(sig_principal) @ R.T)


def tensor4(cv):
    """C_ijkl from a Voigt modulus mapping engineering strains to stresses."""
    c = np.zeros((3, 3, 3, 3))
    for a, (i, j) in enumerate(VOIGT):
        for b, (k, l) in enumerate(VOIGT):
            for ii, jj in {(i, j), (j, i)}:
                for kk, ll in {(k, l), (l, k)}:
                    c[ii, jj, kk, ll] = cv[a, b]
    return c


def in_plane_angle_error(normals, expected):
    """Largest angle [rad] between each expected normal and its closest found one (n ~ -n)."""
    err = 0.0
    for e in expected:
        err = max(err, min(math.acos(min(1.0, abs(float(n @ e)))) for n in normals))
    return err


# --- acoustic tensor ---------------------------------------------------------------------------


def test_acoustic_tensor_matches_the_index_contraction_for_a_nonsymmetric_modulus():
    rng = np.random.default_rng(0)
    cv = rng.normal(size=(6, 6))
    n = rng.normal(size=3)
    n /= np.linalg.norm(n)
    ref = np.einsum("j,ijkl,l->ik", n, tensor4(cv), n)
    assert np.allclose(bf.acoustic_tensor(cv, n), ref, rtol=0, atol=1e-13)


def test_elastic_acoustic_tensor_and_ratio_one():
    lw = law()
    ce = lw.elastic_matrix()
    lam, mu = lw.K - 2 * lw.mu / 3, lw.mu
    n = np.array([0.3, -0.5, 0.8])
    n /= np.linalg.norm(n)
    assert np.allclose(bf.acoustic_tensor(ce, n), mu * np.eye(3) + (lam + mu) * np.outer(n, n), atol=1e-6)
    loc = bf.localization_plane_strain(ce, ce)
    assert loc.min_ratio == pytest.approx(1.0, abs=1e-14) and not loc.localized


def test_determinant_lemma_of_eq8():
    """det A / det A^e = 1 - b_n . (A^e)^-1 . a_n / f:Ce:g (EDE_NOTES), a_n = (Ce:g).n, b_n = n.(Ce:f)."""
    lw = law(psi_deg=5.0)
    p = lw.as_array()
    sig = np.array([-2e4, -9e4, -5e4, 6e3, -2e3, 1e3])
    ce = lw.elastic_matrix()
    f, g = dp.yield_gradient(sig, p), dp.potential_gradient(sig, p)
    cep = dp.perfectly_plastic_tangent(ce, f, g)
    rng = np.random.default_rng(5)
    normals = rng.normal(size=(20, 3))
    normals /= np.linalg.norm(normals, axis=1)[:, None]
    ratios = bf.det_ratios(cep, ce, normals)
    for n, r in zip(normals, ratios):
        ae = bf.acoustic_tensor(ce, n)
        tg, tf = voigt_to_t(ce @ g), voigt_to_t(ce @ f)
        a_n, b_n = tg @ n, n @ tf
        assert r == pytest.approx(1 - b_n @ np.linalg.solve(ae, a_n) / (f @ ce @ g), rel=1e-10, abs=1e-12)


def voigt_to_t(v):
    return np.array([[v[0], v[3], v[5]], [v[3], v[1], v[4]], [v[5], v[4], v[2]]])


def test_plane_strain_determinant_polynomial_of_the_notes():
    """det A(theta) = cos^4 (a0 + a1 t + ... + a4 t^4) for the in-plane (11, 22, 12) tangent."""
    rng = np.random.default_rng(2)
    c = rng.normal(size=(3, 3)) + np.diag([5.0, 5.0, 3.0])
    (c11, c12, c13), (c21, c22, c23), (c31, c32, c33) = c
    a = [c11 * c33 - c13 * c31, c11 * (c23 + c32) - c13 * c21 - c12 * c31,
         c11 * c22 + c13 * c32 + c31 * c23 - c12 * (c33 + c21) - c33 * c21,
         c22 * (c13 + c31) - c23 * c12 - c32 * c21, c22 * c33 - c23 * c32]
    cv = np.zeros((6, 6))
    idx = [0, 1, 3]
    cv[np.ix_(idx, idx)] = c
    cv[2, 2] = cv[4, 4] = cv[5, 5] = 1.0  # decoupled out-of-plane part, A_zz = 1
    for th in (0.2, 1.1, 2.5):
        t = math.tan(th)
        poly = math.cos(th) ** 4 * sum(ak * t**k for k, ak in enumerate(a))
        n = np.array([math.cos(th), math.sin(th), 0.0])
        assert np.linalg.det(bf.acoustic_tensor(cv, n)) == pytest.approx(poly, rel=1e-12)


# --- plane-strain search against Runesson, Ottosen & Peric (1991) ---------------------------------

PS_CASES = [
    (30.0, 5.0, 0.3, (-2.0e4, -9.25e4, -5.0e4), 0.0),
    (30.0, 19.0, 0.3, (-2.0e4, -9.25e4, -6.6e4), 0.3),
    (40.0, 10.0, 0.25, (-1.0e4, -6.0e4, -3.0e4), -0.7),
    (20.0, 0.0, 0.2, (-5.0e4, -1.2e5, -6.0e4), 1.2),
    (35.0, 20.0, 0.35, (5.0e3, -4.0e4, -2.0e4), 2.0),
    (0.0, 0.0, 0.3, (-1.0e4, -5.0e4, -3.0e4), 0.4),
]


@pytest.mark.parametrize("phi,psi,nu,principal,rot", PS_CASES)
def test_plane_strain_search_matches_the_closed_form(phi, psi, nu, principal, rot):
    lw = law(phi, psi, nu)
    c, s = math.cos(rot), math.sin(rot)
    R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    sig = rotated(principal, R)
    loc = bf.localization_at(lw, sig)
    expected = bf.runesson_normals(sig, lw.beta, lw.b, nu)
    assert loc.normals.shape[0] == 2  # the two conjugate bands
    assert in_plane_angle_error(loc.normals[:2], expected) < 1e-6
    assert loc.ratios[0] == pytest.approx(loc.ratios[1], abs=1e-10)  # symmetric about the axes
    # the reported minima are minima of the swept function
    cep = bf.perfectly_plastic_tangent_at(lw, sig)
    for n in loc.normals:
        t = math.atan2(n[1], n[0])
        near = np.array([[math.cos(t + dt), math.sin(t + dt), 0.0] for dt in (-1e-3, 1e-3)])
        assert np.all(bf.det_ratios(cep, lw.elastic_matrix(), near) > loc.ratios[0])


def test_angles_of_the_result_object():
    lw = law(30.0, 5.0)
    loc = bf.localization_at(lw, np.array([-2e4, -9.25e4, -5e4, 0, 0, 0]))
    theta0 = bf.runesson_angle(np.array([-2e4, -9.25e4, -5e4, 0, 0, 0]), lw.beta, lw.b, lw.nu)
    # compression along y: normals at 90 -+ theta0 deg, bands at -+theta0 from horizontal
    t0 = math.degrees(theta0)
    assert sorted(loc.normal_angles_deg) == pytest.approx([90 - t0, 90 + t0], abs=1e-7)
    assert sorted(loc.band_angles_deg) == pytest.approx([-t0, t0], abs=1e-7)
    assert loc.band_angles_deg[0] > 0  # ties: the band rising to the right first
    assert np.all((loc.normal_angles_deg >= 0) & (loc.normal_angles_deg < 180))


# --- 3D search against Rudnicki & Rice (1975) ----------------------------------------------------

RR_CASES = [
    (30.0, 5.0, 0.3, (-2.0e4, -5.0e4, -9.25e4)),
    (35.0, 10.0, 0.25, (-5.0e3, -4.0e4, -6.0e4)),
    (20.0, 0.0, 0.2, (-1.0e4, -1.5e4, -8.0e4)),
    (40.0, 20.0, 0.35, (0.0, -3.0e4, -5.0e4)),
]


@pytest.mark.parametrize("phi,psi,nu,principal", RR_CASES)
def test_3d_search_matches_rudnicki_rice(phi, psi, nu, principal):
    lw = law(phi, psi, nu)
    R, _ = np.linalg.qr(np.random.default_rng(int(phi + psi)).normal(size=(3, 3)))
    sig = rotated(principal, R)
    loc = bf.localization_at(lw, sig, plane_strain=False)
    theta0 = bf.rudnicki_rice_angle(sig, lw.beta, lw.b, nu)
    w, v = np.linalg.eigh(voigt_to_t(sig))  # ascending: v[:, 0] most compressive
    expected = [math.cos(theta0) * v[:, 0] + sg * math.sin(theta0) * v[:, 2] for sg in (1, -1)]
    assert loc.normals.shape[0] == 2
    assert in_plane_angle_error(loc.normals, expected) < 1e-6
    assert np.abs(loc.normals @ v[:, 1]).max() < 1e-7  # in the plane of the extreme principal axes


@pytest.mark.parametrize("phi,psi,nu,axial,lateral", [(30.0, 5.0, 0.3, -9.0e4, -2.0e4), (40.0, 20.0, 0.25, -6.0e4, 0.0)])
def test_3d_search_on_an_axisymmetric_state_finds_the_rudnicki_rice_cone(phi, psi, nu, axial, lateral):
    """Triaxial compression (sigma_2 = sigma_3): every normal of the cone at theta0 from the axis is
    critical; the search returns normals on that cone, whatever the axis's direction."""
    lw = law(phi, psi, nu)
    R, _ = np.linalg.qr(np.random.default_rng(7).normal(size=(3, 3)))
    sig = rotated((axial, lateral, lateral), R)
    loc = bf.localization_at(lw, sig, plane_strain=False)
    theta0 = bf.rudnicki_rice_angle(sig, lw.beta, lw.b, nu)
    axis = R[:, 0]  # the compressive axis, rotated
    assert 0.0 < theta0 < 0.5 * math.pi and loc.normals.shape[0] >= 1
    np.testing.assert_allclose(np.abs(loc.normals @ axis), math.cos(theta0), atol=1e-6)
    # the same state about another axis: the same cone angle
    loc2 = bf.localization_at(lw, rotated((axial, lateral, lateral), np.eye(3)), plane_strain=False)
    np.testing.assert_allclose(np.abs(loc2.normals[:, 0]), math.cos(theta0), atol=1e-6)


# --- slip direction and the driver path -------------------------------------------------------------


def test_slip_is_the_null_vector_and_matches_the_closed_form():
    """A m = 0 with m proportional to (A^e)^-1 (Ce:g).n for the rank-one update of eq. (8)."""
    from rockfrac.studies.dp_calibrated import calibrated
    from rockfrac.laws.dp_driver import drive_specimen

    lw = calibrated()
    path = drive_specimen(lw, axial_strain=-0.02, steps=400, stop_at_onset=True)
    o = path.onset
    assert o is not None
    c = bf.perfectly_plastic_tangent_at(lw, o.sigma)
    ce = lw.elastic_matrix()
    g = dp.potential_gradient(o.sigma, lw.as_array())
    for n, m, r in zip(o.localization.normals, o.localization.slips, o.localization.ratios):
        assert r <= 0.0 and abs(r) < 1e-9  # det A ~ 0 at the located onset
        a = bf.acoustic_tensor(c, n)
        assert np.linalg.norm(a @ m) < 1e-7 * np.abs(a).max()
        ref = np.linalg.solve(bf.acoustic_tensor(ce, n), voigt_to_t(ce @ g) @ n)
        ref /= np.linalg.norm(ref)
        assert abs(abs(float(m @ ref)) - 1.0) < 1e-9 and m @ n > 0 and np.linalg.norm(m) == pytest.approx(1.0)
    # det A > 0 at the previous converged step, and at its stress along the whole normal sweep
    prev = path.sigma[o.step - 1]
    assert path.det_ratio[o.step - 1] > 0.0
    assert bf.localization_at(lw, prev).min_ratio > 0.0
    assert path.det_ratio[o.step] <= 0.0


# --- CLI -----------------------------------------------------------------------------------------


def test_cli_prints_the_angles_of_the_example(capsys):
    assert main(["bifurcation", str(EXAMPLE)]) == 0
    out = " ".join(capsys.readouterr().out.split())
    assert "56.4065" in out and "-56.4065" in out and "146.4065" in out and "33.5935" in out
    assert "on the yield surface" in out and "onset" in out
    assert main(["bifurcation", str(EXAMPLE), "--3d"]) == 0
    assert "56.4065" in capsys.readouterr().out
    assert main(["bifurcation", str(EXAMPLE), "--stress=-2e4,-5e4,-2e4,0"]) == 0
    out = " ".join(capsys.readouterr().out.split())
    assert "inside the yield surface" in out and "not localized" in out
    # the paper's own parameters at their onset: the CSE cases' crack angle
    assert main(["bifurcation", str(GOSFORD)]) == 0
    out = " ".join(capsys.readouterr().out.split())
    assert f"{math.degrees(table1.CRACK_ANGLE):.4f}" in out and "147.2371" in out and "onset" in out


GOOD = EXAMPLE.read_text()


@pytest.mark.parametrize(
    "edit,args,expected",
    [
        (("nu = 0.3", "nu = 0.5"), [], "[material] nu: Input should be less than 0.5"),
        (("nu = 0.3", "nu = 0.3\nphi = 0.5"), [],
         "[material] phi: unknown key; allowed keys: E, nu, beta, b, kappa0, H"),
        (("beta = ", "betta = "), [], "[material] beta: missing (required)"),
        (("[material]", "[materials]"), [], "missing section [material]"),
        (("H = 43802.9", "H = -1e9"), [], "[material] H: H = -1000000000.0 softens too fast"),
        (("sxy = 0.0", "sxy = 'x'"), [], "[stress] sxy: Input should be a valid number"),
        (("sxy = 0.0", "sxy = 0.0\nsyz = 5.0"), [], "plane strain needs syz = sxz = 0"),
        (("\n[stress]\n", "\n[unused]\n"), [], "unused: unknown key; allowed keys: title, description"),
        (("", ""), ["--stress=1,2"], "--stress: expected 4 or 6 comma-separated numbers"),
        (("", ""), ["--stress=-1e4,-1e4,-1e4,0"], "the stress is hydrostatic"),
    ],
)
def test_bad_material_files_get_a_clean_error(tmp_path, capsys, edit, args, expected):
    old, new = edit
    assert old in GOOD
    path = tmp_path / "m.toml"
    path.write_text(GOOD.replace(old, new, 1) if old else GOOD)
    assert main(["bifurcation", str(path), *args]) == 2
    err = " ".join(capsys.readouterr().err.split())
    assert expected in err, err
    assert "Traceback" not in err
    if not args:
        assert str(path) in err.replace(" ", "") or str(path) in err


def test_missing_stress_and_missing_file(tmp_path, capsys):
    path = tmp_path / "m.toml"
    path.write_text(GOOD.split("\n[stress]\n")[0])
    assert main(["bifurcation", str(path)]) == 2
    assert "no [stress] section and no --stress option" in " ".join(capsys.readouterr().err.split())
    assert main(["bifurcation", str(tmp_path / "none.toml")]) == 2
    assert "no such file" in capsys.readouterr().err
