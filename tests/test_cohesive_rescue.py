"""The rescue of the cohesive return (rockfrac.laws.cohesive_rescue): the bracketed frozen return, the
continuation, and the EP and RP returns' success on the trials their plain Newton failed (stiff
penalties, fully softened surfaces in tension, one-step softening through decades)."""

import math

import numpy as np
import pytest

from rockfrac.laws import cohesive as law
from rockfrac.laws import cohesive_rescue as rescue
from rockfrac.laws import cohesive_solve as solve
from rockfrac.laws import cohesive_system as system
from rockfrac.laws.cohesive_params import N_STATE, S_DGAMMA, S_EPSN, S_EPSS, S_TN, S_TT, CohesiveLaw
from rockfrac.studies.table1 import CSE_LAW

# the grains benchmark's surfaces (benchmarks/fragmentation.py, grain boundaries): brittle, with friction
GRAIN_LAW = dict(GfI=20.0, GfII=40.0, chi_p=5600.0, chi_r=0.0, c_p=4200.0, c_r=0.0, phi_p=0.5236, phi_r=0.3,
                 psi_p=0.05, alpha_chi=200.0, alpha_c=200.0, alpha_phi=50.0, alpha_psi=50.0)


def _ep(du, p, eps=0.0, t_old=(0.0, 0.0)):
    s_old = np.zeros(N_STATE)
    s_old[S_TT], s_old[S_TN] = t_old
    s_old[S_EPSN] = s_old[S_EPSS] = eps
    s_new = np.zeros(N_STATE)
    d = np.zeros((2, 2))
    st = law.ep_update(np.asarray(du, dtype=float), s_old, p, s_new, d)
    return st, s_new, d


def _residual(s_new, du, p, eps, t_old=(0.0, 0.0)):
    """The scaled residual norm of the local problem (backward Euler) at the returned state."""
    x = np.array([s_new[S_TT], s_new[S_TN], s_new[S_EPSN], s_new[S_EPSS], s_new[S_DGAMMA]])
    comp = p[:2].copy()
    ws = np.zeros(3)  # backward Euler: no start-of-flow terms
    r, jac = np.zeros(5), np.zeros((5, 5))
    du = np.asarray(du, dtype=float)
    system._system(x, du, np.asarray(t_old, dtype=float), eps, eps, comp, system._jump_weight(comp, du, p), p,
                   ws, r, jac)
    return np.linalg.norm(r)


@pytest.mark.parametrize("tr, kappa, a_g", [(1e4, 1.0, 1e-14), (1e4, 1e9, 1e-14), (5.0, 3.0, 2.0),
                                            (5.0, 30.0, 2.0), (1e-3, 1e12, 4e3), (7.0, 0.0, 1.0)])
def test_tangential_traction_solves_its_equation_with_its_derivative(tr, kappa, a_g):
    t, g, dt = rescue.tangential_traction(tr, kappa, a_g)
    assert 0.0 <= t <= tr
    assert g == pytest.approx(t / math.hypot(t, a_g), rel=1e-12, abs=1e-300)
    assert t + kappa * g == pytest.approx(tr, rel=1e-13)
    h = 1e-6 * max(kappa, 1.0)
    lo = max(kappa - h, 0.0)  # one-sided at kappa = 0
    fd = (rescue.tangential_traction(tr, kappa + h, a_g)[0] - rescue.tangential_traction(tr, lo, a_g)[0]) / (kappa + h - lo)
    assert dt == pytest.approx(fd, rel=1e-5, abs=1e-12 * tr / max(kappa, 1.0))


def test_tangential_traction_degenerate_hyperbola():
    assert rescue.tangential_traction(5.0, 3.0, 0.0)[:2] == (2.0, 1.0)
    assert rescue.tangential_traction(2.0, 4.0, 0.0)[:2] == (0.0, 0.5)


@pytest.mark.parametrize("case", [(CSE_LAW, 1e9, 0.0, 10.0, 30.0), (CSE_LAW, 1e11, 1e-4, 3.0, 200.0),
                                  (GRAIN_LAW, 1e13, 0.0, 1e3, 0.0), (CSE_LAW, 1e9, 0.01, 1.01, 40.0)])
def test_bracketed_frozen_return_is_on_the_frozen_surface_and_agrees_with_newton(case):
    kw, k, eps, mag, deg = case
    p = CohesiveLaw(**kw, kn=k, kt=k).as_array()
    du = mag * kw["chi_p"] / k * np.array([math.cos(math.radians(deg)), math.sin(math.radians(deg))])
    comp, t_old = p[:2].copy(), np.zeros(2)
    x = np.array([du[0] * k, du[1] * k, eps, eps, 0.0])
    assert rescue.bracketed_frozen_return(x, du, t_old, comp, p)
    chi, c, _, tpsi = law.strengths(eps, eps, p)
    assert x[4] > 0.0
    assert x[1] == pytest.approx(du[1] * k - k * x[4] * tpsi, rel=1e-12, abs=1e-9)
    a_g = c - chi * tpsi
    assert x[0] + k * x[4] * x[0] / math.hypot(x[0], a_g) == pytest.approx(du[0] * k, rel=1e-12, abs=1e-9)
    assert abs(law.yield_function(x[0], x[1], eps, eps, p)) < 1e-10 * (kw["c_p"] + kw["chi_p"])
    y = np.array([du[0] * k, du[1] * k, eps, eps, 0.0])
    if solve._frozen_return(y, du, t_old, comp, p, np.sign(y[0])):  # where Newton converges, the same root
        np.testing.assert_allclose(y[[0, 1, 4]], x[[0, 1, 4]], rtol=1e-8, atol=1e-12)


# trials on which the EP return's Newton from the frozen guess failed before the rescue
# (law, k [Pa/m], eps of the old state, |du| in units of chi_p / k, direction [deg])
FAILED_BEFORE = [
    (CSE_LAW, 1e11, 0.0, 1e4, 0.0),      # 1.6 mm of slip in one step from a virgin point
    (GRAIN_LAW, 1e11, 1e-3, 1e4, 180.0),
    (CSE_LAW, 1e9, 1e-3, 1e3, 330.0),
    (CSE_LAW, 1e9, 0.01, 1.01, 40.0),    # a fully softened surface opened and sheared
    (CSE_LAW, 1e13, 0.003, 3.0, 120.0),
]


def _trial(case):
    """(parameters, jump increment [m], eps of the old state) of a FAILED_BEFORE case."""
    kw, k, eps, mag, deg = case
    du = mag * kw["chi_p"] / k * np.array([math.cos(math.radians(deg)), math.sin(math.radians(deg))])
    return CohesiveLaw(**kw, kn=k, kt=k).as_array(), du, eps


@pytest.mark.parametrize("case", FAILED_BEFORE)
def test_rescued_return_converges_to_the_backward_euler_solution(case):
    p, du, eps = _trial(case)
    st, s_new, _ = _ep(du, p, eps)
    assert st == 1
    assert _residual(s_new, du, p, eps) < 1e-9
    assert s_new[S_DGAMMA] > 0.0
    assert s_new[S_EPSN] >= eps and s_new[S_EPSS] >= eps


@pytest.mark.parametrize("case", FAILED_BEFORE[:3])
def test_rescued_return_tangent_against_central_differences(case):
    p, du, eps = _trial(case)
    st, _, d = _ep(du, p, eps)
    assert st == 1
    h = 1e-6 * np.linalg.norm(du)
    fd = np.zeros((2, 2))
    for j in range(2):
        e = np.zeros(2)
        e[j] = h
        sp, sm = _ep(du + e, p, eps)[1], _ep(du - e, p, eps)[1]
        fd[:, j] = (sp[[S_TT, S_TN]] - sm[[S_TT, S_TN]]) / (2 * h)
    scale = np.abs(fd).max()
    assert scale > 0.0
    np.testing.assert_allclose(d, fd, rtol=0, atol=1e-5 * scale)


def test_rescue_finds_the_root_the_plain_newton_finds():
    """Where the plain Newton converges, the rescue started from scratch lands on the same return."""
    p = CohesiveLaw(**CSE_LAW, kn=1e9, kt=1e9).as_array()
    for deg in (0.0, 30.0, 150.0, 200.0):
        du = 3.0 * 15680.0 / 1e9 * np.array([math.cos(math.radians(deg)), math.sin(math.radians(deg))])
        st, s_new, _ = _ep(du, p)
        assert st == 1
        wk = solve.workspace()
        x = np.zeros(5)
        comp, t_old = p[:2].copy(), np.zeros(2)
        st2 = rescue.rescue_return(x, du, t_old, t_old.copy(), np.int64(system.START_CROSSING), 0.0, 0.0, comp, p,
                                   wk[8], wk[9], wk)
        assert st2 > 0
        np.testing.assert_allclose(x, s_new[[S_TT, S_TN, S_EPSN, S_EPSS, S_DGAMMA]], rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize("name, kw", [("paper", CSE_LAW), ("grains", GRAIN_LAW)])
@pytest.mark.parametrize("k", [1e11, 1e13])
def test_no_ep_return_fails_with_stiff_penalties(name, kw, k):
    """Backward Euler, stiff penalties: every trial up to 1e4 times the strength, in every direction,
    from virgin, softening and fully softened points and from a loaded one, returns."""
    p = CohesiveLaw(**kw, kn=k, kt=k).as_array()
    failed = []
    for eps in (0.0, 1e-4, 1e-3, 1e-2):
        for mag in (1.01, 3.0, 100.0, 1e4):
            for deg in range(0, 360, 15):
                for t_old in ((0.0, 0.0), (0.1 * kw["c_p"], -kw["chi_p"])):
                    if law.yield_function(*t_old, eps, eps, p) > 0.0:
                        continue
                    du = mag * kw["chi_p"] / k * np.array([math.cos(math.radians(deg)), math.sin(math.radians(deg))])
                    st, s_new, _ = _ep(du, p, eps, t_old)
                    if st < 0 or (st == 1 and _residual(s_new, du, p, eps, t_old) > 1e-9):
                        failed.append((eps, mag, deg, t_old, st))
    assert failed == []


def test_the_element_kernel_rescues_its_failed_points_only():
    """MohrCoulombSurface.ep_points: the compiled point loop leaves a failed return failed (< 0); the
    law's wrapper then solves those points again with the rescue, and their blocks come from it."""
    from rockfrac.laws.mohr_coulomb_surface import MohrCoulombParameters, MohrCoulombSurface

    kw, k, eps, mag, deg = FAILED_BEFORE[3]  # a fully softened surface opened and sheared
    law = MohrCoulombSurface(MohrCoulombParameters(**kw), kn=k, kt=k)
    du = mag * kw["chi_p"] / k * np.array([math.cos(math.radians(deg)), math.sin(math.radians(deg))])
    n = 3  # an elastic point, the failing one, and the same again
    frame = np.broadcast_to(np.eye(2), (n, 2, 2)).copy()
    weight = np.full(n, 0.5)
    djump = np.array([1e-3 * du, du, du])
    s_old = np.zeros((n, N_STATE))
    s_old[1:, S_EPSN] = s_old[1:, S_EPSS] = eps
    d_old = np.zeros((n, 2, 2))

    def run(kernel_only):
        s_new, d_new = np.zeros((n, N_STATE)), np.zeros((n, 2, 2))
        fe, ke, status = np.zeros((n, 4)), np.zeros((n, 4, 4)), np.zeros(n, dtype=np.int64)
        if kernel_only:
            type(law).ep_kernel(frame, weight, djump, s_old, d_old, law.p, s_new, d_new, fe, ke, status)
        else:
            law.ep_points(frame, weight, djump, s_old, d_old, s_new, d_new, fe, ke, status)
        return s_new, d_new, fe, status

    _, _, _, plain = run(True)
    assert plain[0] == 0 and plain[1] < 0 and plain[2] < 0
    s_new, d_new, fe, status = run(False)
    assert status.tolist() == [0, 1, 1]
    st, ref, d_ref = _ep(du, law.p, eps)
    assert st == 1
    np.testing.assert_array_equal(s_new[1], ref)
    np.testing.assert_array_equal(d_new[1], d_ref)
    # the blocks of the rescued point: w T on the plus side, -w T on the minus side
    np.testing.assert_allclose(fe[1], [-0.5 * ref[S_TT], -0.5 * ref[S_TN], 0.5 * ref[S_TT], 0.5 * ref[S_TN]],
                               rtol=1e-14, atol=1e-300)


# all but the second, whose RP return converges without the rescue
@pytest.mark.parametrize("case", [c for j, c in enumerate(FAILED_BEFORE) if j != 1])
def test_the_rp_kernel_rescues_its_failed_points_to_the_ep_return_with_k_equal_to_r(case):
    """MohrCoulombSurface.rp_points at a constrained point with lambda = 0 and the augmented trial
    r h (the grains' RP runs stopped on such returns at min_step): the compiled loop fails it, the
    law's wrapper rescues it, and the return is the EP return with kn = kt = r from T_old = 0 (the
    same backward-Euler problem), its tangent and its multiplier rows w (T - lambda) included."""
    from rockfrac.laws.mohr_coulomb_surface import MohrCoulombParameters, MohrCoulombSurface

    kw, k, eps, mag, deg = case
    law = MohrCoulombSurface(MohrCoulombParameters(**kw))  # rigid-plastic: no penalty
    du = mag * kw["chi_p"] / k * np.array([math.cos(math.radians(deg)), math.sin(math.radians(deg))])
    frame, weight, lam = np.eye(2)[None].copy(), np.full(1, 0.5), np.zeros((1, 2))
    s_old = np.zeros((1, N_STATE))
    s_old[:, S_EPSN] = s_old[:, S_EPSS] = eps

    def run(kernel_only):
        s_new, d_new = np.zeros((1, N_STATE)), np.zeros((1, 2, 2))
        fe, ke = np.zeros((1, 6)), np.zeros((1, 6, 6))
        status, switched = np.zeros(1, dtype=np.int64), np.zeros(1, dtype=np.int64)
        args = (frame, weight, du[None].copy(), lam, k, np.zeros(1), np.zeros(1, dtype=bool), s_old,
                np.zeros((1, 2, 2)), np.zeros(1))
        if kernel_only:
            type(law).rp_kernel(*args, law.p, s_new, d_new, fe, ke, status, switched)
        else:
            law.rp_points(*args, s_new, d_new, fe, ke, status, switched)
        return s_new, d_new, fe, status, switched

    assert run(True)[3][0] < 0
    s_new, d_new, fe, status, switched = run(False)
    assert status[0] == 1 and switched[0] == 1  # plastic, from the constrained state of the last iterate
    st, ref, d_ref = _ep(du, CohesiveLaw(**kw, kn=k, kt=k).as_array(), eps)
    assert st == 1
    slots = [S_TT, S_TN, S_EPSN, S_EPSS, S_DGAMMA]
    np.testing.assert_allclose(s_new[0, slots], ref[slots], rtol=1e-9, atol=1e-9 * kw["chi_p"] / k)
    np.testing.assert_allclose(d_new[0], d_ref, rtol=1e-7, atol=1e-9 * np.abs(d_ref).max())
    # the multiplier rows: w (T - lambda), lambda = 0
    np.testing.assert_allclose(fe[0, 4:], 0.5 * ref[[S_TT, S_TN]], rtol=1e-9, atol=1e-9 * kw["chi_p"])


def test_a_run_without_failed_points_does_not_compile_the_rescue(tmp_path):
    """The paper's EP and RP cases in a fresh process: no point fails its return, so neither rescue
    kernel is compiled (nor its first-run cost paid)."""
    import subprocess
    import sys

    code = ("import sys; sys.path.insert(0, 'tests')\n"
            "from conftest import paper_case\n"
            "from rockfrac.case.schema import parse_case\n"
            "from rockfrac.runner import run_case\n"
            "from rockfrac.laws import mohr_coulomb_surface as M\n"
            f"s = run_case(parse_case(paper_case('ep', 1e9, axial_steps=40)), r'{tmp_path / 'o'}')\n"
            f"r = run_case(parse_case(paper_case('rp', axial_steps=40)), r'{tmp_path / 'r'}')\n"
            "print('COMPLETED', s.result.completed, r.result.completed, 'RESCUE', len(M.ep_rescue_points.signatures),\n"
            "      len(M.rp_rescue_points.signatures))\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=600,
                          cwd=str(__import__("pathlib").Path(__file__).resolve().parents[1]))
    assert "COMPLETED True True RESCUE 0 0" in done.stdout, done.stdout[-2000:] + done.stderr[-2000:]
