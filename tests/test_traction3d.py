"""The cohesive traction laws in 3D (rockfrac.laws.traction3d), for both registered laws: the
consistent tangent against finite differences, objectivity (about n, and of a rotated interface),
the reduction to the 2D laws (driver and element blocks, EP and RP), the element blocks, the
trapezoidal work rule's refusal and Numba's on-disk cache of the compiled loops."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from itertools import pairwise

import numpy as np
import pytest

from rockfrac.laws import traction3d as t3
from rockfrac.laws.bilinear import Bilinear, BilinearParameters
from rockfrac.laws.mohr_coulomb_surface import MohrCoulombParameters, MohrCoulombSurface

# Table 1 (tests/test_cohesive_law.py), EP with k = 1e9 Pa/m; the bilinear law of tests/test_bilinear_law.py
TABLE1 = dict(GfI=1.0e4, GfII=1.0e4, chi_p=15680.0, chi_r=0.0, c_p=9053.0, c_r=0.0, phi_p=0.5236, phi_r=0.0,
              psi_p=0.087, alpha_chi=2.0e3, alpha_c=2.0e3, alpha_phi=9.0e2, alpha_psi=9.0e2)
SIGMA, GC, BETA = 2e6, 100.0, 0.5  # delta_c = 1e-4 m


def mohr_coulomb(k=1e9, **kw) -> MohrCoulombSurface:
    return MohrCoulombSurface(MohrCoulombParameters(**{**TABLE1, **kw}), kn=k, kt=k)


def bilinear(k=1e13, **kw) -> Bilinear:
    return Bilinear(BilinearParameters(sigma_c=SIGMA, Gc=GC, beta=BETA), kn=k, kt=k)


LAWS = {"mohr_coulomb": mohr_coulomb, "bilinear": bilinear}

# name -> (law keywords, committed 3D state slots, local increment (t1, t2, n) [m], expected status)
CASES = {
    "mohr_coulomb": {
        "elastic": ({}, dict(T_t1=100.0, T_t2=60.0, T_n=-2000.0), (1e-7, -0.5e-7, -1e-7), 0),
        "shear softening": ({}, dict(T_t1=8000.0, T_t2=6000.0, T_n=-2e4, eps_s_p=5e-4,
                                     jump_p_t1=2e-5, jump_p_t2=-1e-5, jump_p_n=1e-6), (2e-6, -1e-6, 0.0), 1),
        "opening and shear": (dict(GfI=0.5e4, GfII=3e4), dict(T_t1=3000.0, T_t2=4000.0, T_n=2000.0, eps_n_p=1e-4,
                                                             eps_s_p=1e-4), (3e-6, -1e-6, 2e-6), 1),
        "pure opening": ({}, {}, (0.0, 0.0, 1.6e-5), 1),
    },
    "bilinear": {
        "elastic": ({}, dict(T_t1=1e5, T_t2=-5e4, T_n=3e5), (1e-8, 2e-8, -1e-8), 0),
        "shear softening": ({}, dict(T_t1=3e5, T_t2=4e5, T_n=-1e6, kappa=4e-5, jump_p_t1=5e-5,
                                     jump_p_t2=-6e-5), (4e-8, 1e-8, -1e-8), 1),
        "opening and shear": ({}, dict(T_t1=1e5, T_t2=1.5e5, T_n=5e5, kappa=1e-5), (5e-8, 1e-8, 1.5e-7), 1),
        "pure opening": ({}, {}, (0.0, 0.0, 3e-7), 1),
    },
}
ALL_CASES = [(law, case) for law in CASES for case in CASES[law]]
# the trial's change [Pa] of a finite-difference step: Mohr-Coulomb next to pure opening curves on the scale
# a_F = c - chi tan(phi) ~ 0.2 Pa of Table 1; the bilinear return stops at |F| <= 1e-13 sigma_c = 2e-7 Pa
FD_TRACTION = {"mohr_coulomb": 0.01, "bilinear": 1.0}


def state(law, **slots) -> np.ndarray:
    """A committed 3D state with the given named slots."""
    names = t3.state_names_3d(type(law))
    s = np.zeros(len(names))
    for k, v in slots.items():
        s[names.index(k)] = v
    return s


def case(law_name, name):
    kw, slots, du, st = CASES[law_name][name]
    law = LAWS[law_name](**kw)
    return law, state(law, **slots), np.array(du), st


def update(law, du, s_old):
    """One 3D EP point update: (status, new state, tangent)."""
    s_new, d = np.zeros_like(s_old), np.zeros((3, 3))
    st = t3.ep_update_3d(t3.trial_function(type(law)), np.asarray(du, dtype=float), s_old, law.p, 1.0 / law.kt,
                         1.0 / law.kn, s_new, d)
    return st, s_new, d


def rel(a, b) -> float:
    return float(np.linalg.norm(np.asarray(a) - np.asarray(b)) / np.linalg.norm(b))


def columns_close(a, b, tol):
    """|a - b| <= tol max|b| column by column (states: each slot in its own units)."""
    a, b = np.asarray(a), np.asarray(b)
    err = np.abs(a - b).max(axis=0) / np.maximum(np.abs(b).max(axis=0), 1e-300)
    assert np.all(err <= tol), err


def rotation(rng) -> np.ndarray:
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q


def about_n(theta) -> np.ndarray:
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def test_state_layout():
    assert t3.state_names_3d(MohrCoulombSurface) == ("T_t1", "T_t2", "T_n", "jump_p_t1", "jump_p_t2", "jump_p_n",
                                                     "eps_n_p", "eps_s_p", "dgamma", "mode")
    for law in (MohrCoulombSurface, Bilinear):
        names = t3.state_names_3d(law)
        assert names[t3.mode_slot_3d(law)] == "mode" and names[t3.dgamma_slot_3d(law)] == "dgamma"


# --- the point update ---------------------------------------------------------------------------


@pytest.mark.parametrize("law_name, name", ALL_CASES)
def test_consistent_tangent_matches_finite_differences(law_name, name):
    law, s_old, du, expected = case(law_name, name)
    st, s_new, d = update(law, du, s_old)
    assert st == expected
    h = FD_TRACTION[law_name] / law.kt
    d_fd = np.zeros((3, 3))
    for j in range(3):
        e = np.zeros(3)
        e[j] = h
        d_fd[:, j] = (update(law, du + e, s_old)[1][:3] - update(law, du - e, s_old)[1][:3]) / (2 * h)
    assert rel(d, d_fd) < 1e-5
    if name == "pure opening":  # the in-plane isotropic limit: T_t stays 0, D_t1t1 = D_t2t2
        assert s_new[0] == 0.0 and s_new[1] == 0.0
        assert d[0, 0] == d[1, 1] and d[0, 1] == 0.0
    if name == "shear softening":  # the old traction is not along the increment: T_t turns
        cross = s_new[0] * s_old[1] - s_new[1] * s_old[0]
        assert abs(cross) > 1e-3 * np.linalg.norm(s_new[:2]) * np.linalg.norm(s_old[:2])
        tr = s_old[:2] + law.kt * du[:2]
        across = np.array([-tr[1], tr[0]]) / np.linalg.norm(tr)  # across the trial: |T_t| / |T_t^tr| kt
        assert 0.0 < across @ d[:2, :2] @ across < (1 - 1e-3) * law.kt


@pytest.mark.parametrize("law_name, name", ALL_CASES)
def test_point_update_is_objective_about_n(law_name, name):
    law, s_old, du, _ = case(law_name, name)
    st, s_new, d = update(law, du, s_old)
    for theta in (0.4, 2.3, -1.7, np.pi):
        q = about_n(theta)
        s_rot = s_old.copy()
        s_rot[0:2] = q[:2, :2] @ s_old[0:2]
        s_rot[3:5] = q[:2, :2] @ s_old[3:5]
        st_r, s_new_r, d_r = update(law, q @ du, s_rot)
        assert st_r == st
        np.testing.assert_allclose(s_new_r[0:3], q @ s_new[0:3], rtol=0, atol=1e-12 * np.abs(s_new[:3]).max())
        np.testing.assert_allclose(s_new_r[3:5], q[:2, :2] @ s_new[3:5], rtol=0,
                                   atol=1e-12 * max(np.abs(s_new[3:5]).max(), 1e-30))
        np.testing.assert_allclose(s_new_r[5:], s_new[5:], rtol=1e-12, atol=0)
        assert rel(d_r, q @ d @ q.T) < 1e-10


# --- reduction to the 2D laws ---------------------------------------------------------------------


def polyline(corners, steps=40) -> np.ndarray:
    corners = np.asarray(corners, dtype=float)
    return np.vstack([a + np.linspace(0.0, 1.0, steps + 1)[1:, None] * (b - a) for a, b in pairwise(corners)])


PATHS = {  # (jump_t, jump_n) corners [m]: compression-shear, reversal, opening
    "mohr_coulomb": [(0, 0), (0, -2e-5), (1.5e-4, -2e-5), (1e-4, 5e-5), (-1e-4, 2e-4)],
    "bilinear": [(0, 0), (0, -1e-7), (3e-5, -1e-7), (-2e-5, 5e-5), (0, 1.5e-4)],
}


@pytest.mark.parametrize("law_name", list(LAWS))
@pytest.mark.parametrize("direction", ["t1", "t2", "30 degrees"])
def test_planar_paths_reproduce_the_2d_law(law_name, direction):
    """Along t1, t2 or any tangential direction (c, s) the 3D states are the 2D ones."""
    c, s = {"t1": (1.0, 0.0), "t2": (0.0, 1.0), "30 degrees": (np.cos(np.pi / 6), np.sin(np.pi / 6))}[direction]
    law = LAWS[law_name]()
    j2 = polyline(PATHS[law_name])
    ref = law.drive(j2)
    d3 = t3.drive_3d(law, np.column_stack([c * j2[:, 0], s * j2[:, 0], j2[:, 1]]))
    assert ref["jump_p_t"].min() < 0 < ref["jump_p_t"].max() and ref["jump_p_n"].max() > 0  # slides both ways, opens
    pairs = [("T_t1", c, "T_t"), ("T_t2", s, "T_t"), ("T_n", 1.0, "T_n"), ("jump_p_t1", c, "jump_p_t"),
             ("jump_p_t2", s, "jump_p_t"), ("jump_p_n", 1.0, "jump_p_n")]
    pairs += [(r, 1.0, r) for r in law.record_names]
    for k3, f, k2 in pairs:
        scale = np.abs(ref[k2]).max()
        np.testing.assert_allclose(d3[k3], f * ref[k2], rtol=0, atol=1e-12 * scale, err_msg=k3)
    if direction == "t1":
        assert np.all(d3["T_t2"] == 0.0) and np.all(d3["jump_p_t2"] == 0.0)
    if direction == "t2":
        assert np.all(d3["T_t1"] == 0.0) and np.all(d3["jump_p_t1"] == 0.0)


def test_driver_reports_the_failing_step_as_the_2d_law():
    law = Bilinear(BilinearParameters(sigma_c=SIGMA, Gc=GC, beta=BETA), kn=1e13, kt=1e9)  # kt / beta^2 below the
    u = np.linspace(0.0, 4e-7, 41)[1:]  # softening slope 2e10 Pa/m: no unique return once it opens with a little shear
    with pytest.raises(RuntimeError, match=r"path step (\d+)") as e2:
        law.drive(np.column_stack([1e-3 * u, u]))
    step = int(e2.value.args[0].split("path step ")[1].split()[0])
    assert step == 21  # yields at 2e-7 m
    with pytest.raises(RuntimeError, match=rf"bilinear law \(3D\).*path step {step} "):
        t3.drive_3d(law, np.column_stack([0.6e-3 * u, -0.8e-3 * u, u]))
    with pytest.raises(ValueError, match=r"shape \(n, 3\)"):
        t3.drive_3d(bilinear(), np.zeros((3, 2)))


def embedded_frames(angles) -> tuple[np.ndarray, np.ndarray]:
    """2D frames (rows t, n) and the same interfaces in 3D: rows t1 = t, t2 = -z, n."""
    c, s = np.cos(angles), np.sin(angles)
    f2 = np.stack([np.stack([c, s], 1), np.stack([-s, c], 1)], 1)
    f3 = np.zeros((len(angles), 3, 3))
    f3[:, 0, :2], f3[:, 2, :2], f3[:, 1, 2] = f2[:, 0], f2[:, 1], -1.0
    return f2, f3


def embed(s2) -> np.ndarray:
    s3 = np.zeros((s2.shape[0], s2.shape[1] + 2))
    s3[:, [0, 2, 3, 5]] = s2[:, :4]
    s3[:, 6:] = s2[:, 4:]
    return s3


@pytest.mark.parametrize("law_name", list(LAWS))
def test_ep_blocks_of_a_planar_interface_are_the_2d_blocks(law_name):
    """Two steps of the EP form (virgin, then committed states, some plastic) on in-plane jumps."""
    law = LAWS[law_name]()
    rng = np.random.default_rng(1)
    n = 40
    f2, f3 = embedded_frames(rng.uniform(-np.pi, np.pi, n))
    w = rng.uniform(0.5, 2.0, n)
    scale = 3.0 * law.scale / law.kt
    s2, d2 = np.zeros((n, law.n_state)), np.zeros((n, 2, 2))
    s3, d3 = embed(s2), np.zeros((n, 3, 3))
    plastic = 0
    for _ in range(2):
        dj = rng.normal(size=(n, 2)) * scale
        dj[:3] = 0.0  # committed points with no increment
        n2, dn2, fe2, ke2, st2 = np.zeros_like(s2), np.zeros_like(d2), np.zeros((n, 4)), np.zeros((n, 4, 4)), \
            np.zeros(n, np.int64)
        law.ep_points(f2, w, dj, s2, d2, n2, dn2, fe2, ke2, st2)
        n3, dn3, fe3, ke3, st3 = np.zeros_like(s3), np.zeros_like(d3), np.zeros((n, 6)), np.zeros((n, 6, 6)), \
            np.zeros(n, np.int64)
        t3.ep_form_3d(law, f3, w, np.column_stack([dj, np.zeros(n)]), s3, d3, n3, dn3, fe3, ke3, st3)
        np.testing.assert_array_equal(st3, st2)
        assert np.all(st2 >= 0)
        columns_close(n3, embed(n2), 1e-12)
        np.testing.assert_allclose(fe3[:, [0, 1, 3, 4]], fe2, rtol=0, atol=1e-12 * np.abs(fe2).max())
        np.testing.assert_array_equal(fe3[:, [2, 5]], 0.0)
        idx = np.ix_(range(n), [0, 1, 3, 4], [0, 1, 3, 4])
        np.testing.assert_allclose(ke3[idx], ke2, rtol=0, atol=1e-12 * np.abs(ke2).max())
        plastic += int(np.sum(st2 == 1))
        s2, d2, s3, d3 = n2, dn2, n3, dn3
    assert plastic >= 10


@pytest.mark.parametrize("law_name", list(LAWS))
def test_rp_blocks_of_a_planar_interface_are_the_2d_blocks(law_name):
    """The RP form at the augmented trial, with pinned and junction points, on in-plane jumps."""
    law = LAWS[law_name](k=None)
    aug = 100.0 * law.softening_modulus()
    rng = np.random.default_rng(2)
    n = 40
    f2, f3 = embedded_frames(rng.uniform(-np.pi, np.pi, n))
    w = rng.uniform(0.5, 2.0, n)
    lam2 = rng.normal(size=(n, 2)) * 0.7 * law.scale
    dj = rng.normal(size=(n, 2)) * law.scale / aug
    eps = np.where(np.arange(n) % 5 == 0, 0.3, 0.0)
    pinned = np.arange(n) % 7 == 3
    mode_prev = np.zeros(n)
    s2, d2 = np.zeros((n, law.n_state)), np.zeros((n, 2, 2))
    n2, dn2, fe2, ke2 = np.zeros_like(s2), np.zeros_like(d2), np.zeros((n, 6)), np.zeros((n, 6, 6))
    st2, sw2 = np.zeros(n, np.int64), np.zeros(n, np.int64)
    law.rp_points(f2, w, dj, lam2, aug, eps, pinned, s2, d2, mode_prev, n2, dn2, fe2, ke2, st2, sw2)
    s3 = embed(s2)
    n3, dn3, fe3, ke3 = np.zeros_like(s3), np.zeros((n, 3, 3)), np.zeros((n, 9)), np.zeros((n, 9, 9))
    st3, sw3 = np.zeros(n, np.int64), np.zeros(n, np.int64)
    z = np.zeros((n, 1))
    t3.rp_form_3d(law, f3, w, np.hstack([dj, z]), np.hstack([lam2, z]), aug, eps, pinned, s3, np.zeros((n, 3, 3)),
                  mode_prev, n3, dn3, fe3, ke3, st3, sw3)
    np.testing.assert_array_equal(st3, st2)
    np.testing.assert_array_equal(sw3, sw2)
    assert 10 <= np.sum(st2 == 1) and np.sum(st2 == 0) >= 10
    columns_close(n3, embed(n2), 1e-11)
    cols = [0, 1, 3, 4, 6, 7]
    np.testing.assert_allclose(fe3[:, cols], fe2, rtol=0, atol=1e-11 * np.abs(fe2).max())
    np.testing.assert_allclose(ke3[np.ix_(range(n), cols, cols)], ke2, rtol=0, atol=1e-11 * np.abs(ke2).max())
    np.testing.assert_array_equal(fe3[:, [2, 5]], 0.0)


# --- element blocks ---------------------------------------------------------------------------


def ep_blocks(law, frame, dj, s_old, d_old=None, w=None):
    n = frame.shape[0]
    w = np.ones(n) if w is None else w
    d_old = np.zeros((n, 3, 3)) if d_old is None else d_old
    s_new, d_new, fe, ke, st = np.zeros_like(s_old), np.zeros((n, 3, 3)), np.zeros((n, 6)), np.zeros((n, 6, 6)), \
        np.zeros(n, np.int64)
    t3.ep_form_3d(law, frame, w, dj, s_old, d_old, s_new, d_new, fe, ke, st)
    return s_new, d_new, fe, ke, st


@pytest.mark.parametrize("law_name", list(LAWS))
def test_rotated_interface_gives_rotated_forces_and_stiffness(law_name):
    rng = np.random.default_rng(3)
    names = list(CASES[law_name])
    law = LAWS[law_name]()
    n = len(names)
    frame = np.stack([rotation(rng) for _ in range(n)])
    s_old = np.stack([state(law, **CASES[law_name][k][1]) for k in names])
    du = np.stack([CASES[law_name][k][2] for k in names])
    dj = np.einsum("nji,nj->ni", frame, du)  # global jump R^T du
    w = rng.uniform(0.5, 2.0, n)
    s1, _, fe, ke, st = ep_blocks(law, frame, dj, s_old, w=w)
    assert sorted(st) == sorted(CASES[law_name][k][3] for k in names)
    for _ in range(3):
        g = rotation(rng)
        s1r, _, fer, ker, str_ = ep_blocks(law, frame @ g.T, dj @ g.T, s_old, w=w)
        np.testing.assert_array_equal(str_, st)
        gg = np.kron(np.eye(2), g)
        np.testing.assert_allclose(fer, fe @ gg.T, rtol=0, atol=1e-11 * np.abs(fe).max())
        for i in range(n):
            assert rel(ker[i], gg @ ke[i] @ gg.T) < 1e-9  # pure opening: T_t^tr ~ 1e-12 Pa of round-off
        columns_close(s1r, s1, 1e-10)


@pytest.mark.parametrize("law_name", list(LAWS))
def test_blocks_elastic_balance_and_committed_start(law_name):
    rng = np.random.default_rng(4)
    law = LAWS[law_name]()
    n = 8
    frame = np.stack([rotation(rng) for _ in range(n)])
    u = rng.normal(size=(n, 6)) * 0.05 * law.scale / law.kt  # (minus xyz, plus xyz): elastic
    w = rng.uniform(0.5, 2.0, n)
    _, d_new, fe, ke, st = ep_blocks(law, frame, u[:, 3:] - u[:, :3], state(law)[None].repeat(n, 0), w=w)
    assert np.all(st == 0)
    kk = np.array([law.kt, law.kt, law.kn])
    np.testing.assert_allclose(d_new, np.broadcast_to(np.diag(kk), (n, 3, 3)), rtol=1e-15, atol=1e-15 * law.kt)
    np.testing.assert_allclose(fe, np.einsum("nij,nj->ni", ke, u), rtol=0, atol=1e-12 * np.abs(fe).max())
    np.testing.assert_allclose(ke, ke.transpose(0, 2, 1), rtol=0, atol=1e-14 * np.abs(ke).max())
    # plastic points: the forces on the two sides balance, and the rows of K too
    names = list(CASES[law_name])
    s_old = np.stack([state(law, **CASES[law_name][k][1]) for k in names])
    fr = np.stack([rotation(rng) for _ in names])
    dj = np.einsum("nji,nj->ni", fr, np.stack([CASES[law_name][k][2] for k in names]))
    s1, d1, fe, ke, st = ep_blocks(law, fr, dj, s_old)
    assert np.all(fe[:, :3] + fe[:, 3:] == 0.0) and np.all(ke[:, :3] + ke[:, 3:] == 0.0)
    # a committed plastic point with no increment keeps its traction and its tangent
    plastic = st == 1
    s2, d2, _, _, st2 = ep_blocks(law, fr, np.zeros_like(dj), s1, d_old=d1)
    np.testing.assert_array_equal(st2[plastic], 1)
    dg = t3.dgamma_slot_3d(type(law))
    keep = np.delete(np.arange(s1.shape[1]), dg)
    np.testing.assert_array_equal(s2[plastic][:, keep], s1[plastic][:, keep])
    np.testing.assert_array_equal(s2[plastic, dg], 0.0)
    np.testing.assert_array_equal(d2[plastic], d1[plastic])


@pytest.mark.parametrize("law_name", list(LAWS))
def test_rp_stiffness_is_the_derivative_of_the_rp_forces(law_name):
    """ke (n, 9, 9) against central differences of fe in the 9 dofs (minus, plus, lambda) at plastic,
    constrained and constrained-junction points of a rotated interface."""
    law = LAWS[law_name](k=None)
    aug = 100.0 * law.softening_modulus()
    rng = np.random.default_rng(5)
    n = 6
    frame = np.stack([rotation(rng) for _ in range(n)])
    lam_l = np.array([[0.3, 0.4, 0.9], [0.5, -0.2, 0.6], [0.1, 0.1, 0.2], [0.0, 0.0, 1.05], [0.2, -0.3, 0.95],
                      [-0.1, 0.2, 0.1]]) * law.scale
    h_l = np.array([[1, 1, 1], [1, -2, 1], [0.1, 0, 0.1], [0, 0, 0.1], [1, -2, 3], [0, 0.1, 0.1]]) * 0.02 * law.scale / aug
    lam = np.einsum("nji,nj->ni", frame, lam_l)
    eps = np.array([0, 0, 0.3, 0, 0, 0.3])
    pinned = np.zeros(n, dtype=bool)
    s_old = np.zeros((n, len(t3.state_names_3d(type(law)))))
    s_old[:, :3] = 0.5 * lam_l

    def blocks(x):
        """x (n, 9): minus, plus, lambda."""
        fe, ke = np.zeros((n, 9)), np.zeros((n, 9, 9))
        st, sw = np.zeros(n, np.int64), np.zeros(n, np.int64)
        t3.rp_form_3d(law, frame, np.ones(n), np.einsum("nji,nj->ni", frame, h_l) + x[:, 3:6] - x[:, :3],
                      lam + x[:, 6:], aug, eps, pinned, s_old, np.zeros((n, 3, 3)), np.zeros(n), np.zeros_like(s_old),
                      np.zeros((n, 3, 3)), fe, ke, st, sw)
        return fe, ke, st

    _, ke, st = blocks(np.zeros((n, 9)))
    assert list(st) == [1, 1, 0, 1, 1, 0]
    step = np.r_[np.full(6, FD_TRACTION[law_name] / aug), np.full(3, FD_TRACTION[law_name])]
    k_fd = np.zeros((n, 9, 9))
    for j in range(9):
        x = np.zeros((n, 9))
        x[:, j] = step[j]
        k_fd[:, :, j] = (blocks(x)[0] - blocks(-x)[0]) / (2 * step[j])
    # the kernel writes the matrix term -eps w of a constrained junction pair's multiplier rows; their
    # residual term is CohesiveRP's (it keeps the reference tractions): the derivative is the rest
    for i in np.flatnonzero(eps):
        k_fd[i, 6:, 6:] -= eps[i] * np.eye(3)
    for i in range(n):
        for j in range(9):  # column by column: displacement and multiplier columns have their own units
            col = ke[i, :, j]
            assert np.linalg.norm(k_fd[i, :, j] - col) <= 1e-5 * np.linalg.norm(col), (i, j)


# --- refusal, threads and the on-disk cache ---------------------------------------------------


def test_trapezoidal_work_rule_is_refused_in_3d():
    law = mohr_coulomb(work_rule="trapezoidal")
    msg = r"work_rule = 'trapezoidal' is 2D only.*use 'backward_euler'"
    with pytest.raises(ValueError, match=msg):
        t3.drive_3d(law, np.zeros((2, 3)))
    s = np.zeros((1, 10))
    with pytest.raises(ValueError, match=msg):
        t3.ep_form_3d(law, np.eye(3)[None], np.ones(1), np.zeros((1, 3)), s, np.zeros((1, 3, 3)), s.copy(),
                      np.zeros((1, 3, 3)), np.zeros((1, 6)), np.zeros((1, 6, 6)), np.zeros(1, np.int64))
    t3.check_3d(mohr_coulomb())  # the default backward Euler has a 3D form


def test_a_second_process_loads_the_3d_kernels_from_the_cache(tmp_path):
    script = textwrap.dedent("""
        import numpy as np
        from rockfrac.laws import traction3d as t3
        from rockfrac.laws.bilinear import Bilinear, BilinearParameters
        law = Bilinear(BilinearParameters(sigma_c=2e6, Gc=100.0), kn=1e13, kt=1e13)
        t3.drive_3d(law, np.array([[1e-7, 1e-7, 2e-7], [2e-7, 0.0, 4e-7]]))
        s = np.zeros((1, 9))
        t3.ep_form_3d(law, np.eye(3)[None], np.ones(1), np.full((1, 3), 1e-7), s, np.zeros((1, 3, 3)), s.copy(),
                      np.zeros((1, 3, 3)), np.zeros((1, 6)), np.zeros((1, 6, 6)), np.zeros(1, np.int64))
        misses = sum(sum(k.stats.cache_misses.values()) for k in (t3._drive_kernel, t3.ep_points_3d.serial))
        print(misses, t3.trial_function(Bilinear).cache_hits)
    """)
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path)}
    runs = [subprocess.run([sys.executable, "-c", script], env=env, capture_output=True, text=True, check=True)
            for _ in range(2)]
    assert runs[0].stdout.split() == ["2", "0"]  # the first process compiles
    assert runs[1].stdout.split() == ["0", "1"]  # the second loads everything


def test_parallel_loops_give_the_serial_bits(monkeypatch):
    """600 points (3 chunks of scratch) of both forms on Numba's threads and on the calling thread."""
    from rockfrac import threads

    law = mohr_coulomb()
    rng = np.random.default_rng(6)
    n = 600
    frame = np.stack([rotation(rng) for _ in range(n)])
    dj = rng.normal(size=(n, 3)) * 1.5 * law.scale / law.kt
    lam = rng.normal(size=(n, 3)) * 0.4 * law.scale
    s_old = np.zeros((n, 10))
    out = {}
    for path in ("serial", "parallel"):
        monkeypatch.setattr(threads, "FORCE", path)
        s_new, d_new, fe, ke, st = ep_blocks(law, frame, dj, s_old)
        fe9, ke9, st9, sw = np.zeros((n, 9)), np.zeros((n, 9, 9)), np.zeros(n, np.int64), np.zeros(n, np.int64)
        t3.rp_form_3d(law, frame, np.ones(n), 0.3 * dj * law.kt / 1e10, lam, 1e10, np.zeros(n), np.zeros(n, bool), s_old,
                      np.zeros((n, 3, 3)), np.zeros(n), np.zeros_like(s_old), np.zeros((n, 3, 3)), fe9, ke9, st9, sw)
        out[path] = (s_new, d_new, fe, ke, st, fe9, ke9, st9)
    st, st9 = out["serial"][4], out["serial"][7]
    assert np.all(st >= 0) and np.all(st9 >= 0) and 50 < np.sum(st == 1) < n - 50 and 50 < np.sum(st9 == 1) < n - 50
    for a, b in zip(out["serial"], out["parallel"]):
        np.testing.assert_array_equal(a, b)
