"""The bilinear law plug-in against its closed forms: the softening branches in opening and shear,
the fracture energy at full separation, contact, unloading, tangents against finite differences,
and through the FE model and the command line."""

from __future__ import annotations

import numpy as np
import pytest

from rockfrac.case.schema import parse_case
from rockfrac.cli import main
from rockfrac.laws.bilinear import N_STATE, S_KAPPA, S_MODE, Bilinear, BilinearParameters, return_map
from rockfrac.output.csvout import read_csv
from rockfrac.runner import run_case

SIGMA, GC, K = 2e6, 100.0, 1e13  # delta_c = 2 Gc / sigma = 1e-4 m; the penalty 1e13 Pa/m


def law(beta=1.0, k=K) -> Bilinear:
    return Bilinear(BilinearParameters(sigma_c=SIGMA, Gc=GC, beta=beta), kn=k, kt=k)


def work(t: np.ndarray, u_p: np.ndarray, peak: float) -> float:
    """Trapezoidal integral of t d(u_p) along the plastic part of a path, from the yield point
    (peak, 0) on (exact for the piecewise-linear branches)."""
    t, u_p = np.r_[peak, t[u_p > 0]], np.r_[0.0, u_p[u_p > 0]]
    return float(np.sum(0.5 * (t[1:] + t[:-1]) * np.diff(u_p)))


def test_pure_opening_follows_the_bilinear_branch_and_dissipates_gc():
    lw = law()
    delta_c = 2 * GC / SIGMA
    u = np.linspace(0.0, 1.5 * delta_c, 301)
    d = lw.drive(np.column_stack([np.zeros_like(u), u]))
    elastic = d["jump_n"] <= SIGMA / K
    np.testing.assert_allclose(d["T_n"][elastic], K * d["jump_n"][elastic], rtol=1e-12)
    soft = (d["jump_p_n"] > 0) & (d["jump_p_n"] < delta_c)
    np.testing.assert_allclose(d["T_n"][soft], SIGMA * (1 - d["jump_p_n"][soft] / delta_c), rtol=1e-9, atol=1e-6)
    np.testing.assert_allclose(d["T_n"] + K * d["jump_p_n"], K * d["jump_n"], rtol=1e-12, atol=1e-6)  # elastic part
    assert np.all(d["T_n"][d["jump_n"] > delta_c + SIGMA / K] == 0.0)  # separated
    np.testing.assert_allclose(work(d["T_n"], d["jump_p_n"], SIGMA), GC, rtol=1e-9)
    np.testing.assert_allclose(d["kappa"], d["jump_p_n"], rtol=1e-12)
    assert np.all(d["T_t"] == 0.0)


@pytest.mark.parametrize("beta", [0.5, 1.0, 2.0])
def test_pure_shear_softens_from_beta_sigma_and_dissipates_gc(beta):
    lw = law(beta)
    delta_c = 2 * GC / SIGMA
    u = np.linspace(0.0, 1.2 * delta_c / beta + beta * SIGMA / K, 401)
    d = lw.drive(np.column_stack([u, np.zeros_like(u)]))
    assert 0.99 * beta * SIGMA < d["T_t"].max() <= beta * SIGMA * (1 + 1e-12)
    soft = (d["jump_p_t"] > 0) & (d["kappa"] < delta_c)
    np.testing.assert_allclose(d["T_t"][soft], beta * SIGMA * (1 - beta * d["jump_p_t"][soft] / delta_c), rtol=1e-9,
                               atol=1e-6)
    np.testing.assert_allclose(work(d["T_t"], d["jump_p_t"], beta * SIGMA), GC, rtol=2e-5)  # beta s x d(kappa / beta); the last step crosses full failure
    np.testing.assert_allclose(d["kappa"], beta * d["jump_p_t"], rtol=1e-12)


def test_compression_carries_contact_without_friction_and_does_not_yield():
    lw = law()
    d = lw.drive(np.array([[0.0, -1e-6], [1e-7, -1e-6], [3e-6, -1e-6]]))
    np.testing.assert_allclose(d["T_n"], -K * 1e-6)  # contact at the penalty
    assert d["T_t"][1] == pytest.approx(K * 1e-7)  # elastic shear below beta sigma
    assert d["T_t"][2] < SIGMA and d["kappa"][2] > 0  # shear softens the strength, compression does not


def test_unloading_is_elastic_and_keeps_the_plastic_opening():
    lw = law()
    path = np.array([[0.0, 5e-5], [0.0, 2e-5], [0.0, 5e-5], [0.0, 6e-5]])
    d = lw.drive(path)
    up = d["jump_p_n"][0]
    assert d["jump_p_n"][1] == up and d["T_n"][1] == pytest.approx(K * (2e-5 - up))
    assert d["T_n"][2] == pytest.approx(d["T_n"][0], rel=1e-9)  # back on the branch where it left
    assert d["jump_p_n"][3] > up


@pytest.mark.parametrize("form", ["ep", "rp"])
@pytest.mark.parametrize("jump", [(2e-6, 3e-6), (-4e-6, 1e-6), (5e-6, -2e-6), (0.0, 4e-6)])
def test_consistent_tangent_matches_finite_differences(form, jump):
    """dT/d[[u]] of one step from a state that has begun softening, against central differences."""
    lw = law(1.3, k=1e12)
    c = 1e-12 if form == "ep" else 1.0 / 2e12  # RP: the augmented form with r = 2e12
    s0 = np.zeros(N_STATE)
    s0[S_KAPPA] = 1e-5
    s0[S_MODE] = 1.0

    def traction(du):
        s1, d = np.empty(N_STATE), np.empty((2, 2))
        status = return_map(du[0] / c, du[1] / c, c, c, s0, lw.p, s1, d)
        return s1[:2].copy(), d, status

    du = np.array(jump)
    t, d, status = traction(du)
    assert status == 1  # plastic
    h = 1e-12
    fd = np.column_stack([(traction(du + h * e)[0] - traction(du - h * e)[0]) / (2 * h) for e in np.eye(2)])
    np.testing.assert_allclose(d, fd, rtol=2e-5, atol=1e-6 * np.abs(fd).max())


def tension_case(form: str, steps: int) -> dict:
    """The paper's specimen cut horizontally, pulled apart: mode I to full separation."""
    coh = {"law": "bilinear", "form": form, "sigma_c": 2e4, "Gc": 1.0}
    if form == "ep":
        coh.update(kn=1e12, kt=1e12)
    return {"mesh": {"crack_angle": 0.0}, "bulk": {"E": 1.5e7, "nu": 0.3}, "cohesive": coh,
            "loading": {"confinement": 0.0, "axial_displacement": -3e-4, "axial_steps": steps, "control": "path"},
            "output": {"picture": False}}


@pytest.mark.parametrize("form", ["ep", "rp"])
def test_fe_opening_to_full_separation_dissipates_gc_times_the_ligament(tmp_path, form):
    """The law's own account is G_c x ligament exactly; the time-integrated dissipation (the one the
    energy balance closes with) converges to it with the step (its onset step is part elastic)."""
    errors = []
    for steps in (100, 200):
        out = tmp_path / f"{form}{steps}"
        run_case(parse_case(tension_case(form, steps)), out)
        h = read_csv(out / "history.csv")
        pts = read_csv(out / "points.csv")
        last = pts["step"] == pts["step"].max()
        assert np.all(pts["strength"][last] == 0.0)  # separated
        ligament = 0.04  # the specimen's width [m]
        np.testing.assert_allclose(h["D_surface_law"][-1], 1.0 * ligament, rtol=1e-12)
        errors.append(abs(h["D_dissipated"][-1] / ligament - 1.0))
        assert abs(h["F_axial"][-1]) < 1e-6 * abs(h["F_axial"]).max()  # no force left
        assert np.abs(h["energy_error"]).max() < 1e-9 * h["W_external"][-1]
    assert errors[1] < 1e-2 and errors[1] < 0.6 * errors[0] + 1e-12


def test_drive_cli_runs_any_registered_law(tmp_path, capsys):
    law_file = tmp_path / "law.toml"
    law_file.write_text('[law]\nlaw = "bilinear"\nkn = 1e13\nkt = 1e13\nsigma_c = 2e6\nGc = 100.0\n')
    path = tmp_path / "path.csv"
    path.write_text("jump_t,jump_n\n" + "\n".join(f"0,{x:.6e}" for x in np.linspace(0, 2e-4, 41)[1:]) + "\n")
    assert main(["drive", str(law_file), "--path", str(path), "--out", str(tmp_path / "o")]) == 0
    d = read_csv(tmp_path / "o" / "drive.csv")
    assert list(d)[:7] == ["step", "jump_t", "jump_n", "T_t", "T_n", "jump_p_t", "jump_p_n"]
    assert "strength" in d and d["T_n"][-1] == 0.0
    law_file.write_text('[law]\nlaw = "exponential"\nkn = 1e13\nkt = 1e13\n')
    assert main(["drive", str(law_file), "--path", str(path), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "[law]" in err and "law must be one of ['bilinear', 'mohr_coulomb']" in " ".join(err.split())
