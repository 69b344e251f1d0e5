"""The fast assembly paths equal their reference paths: bit for bit where the arithmetic is the same
(fused elastic assembly, scratch-array return maps, B's zeros skipped), to round-off against a plain
NumPy/SciPy COO assembly of the whole residual and tangent, serial against two threads, and the
load-step history of a grains run unchanged when every fast path is swapped for its reference."""

import math
from pathlib import Path

import numba as nb
import numpy as np
import pytest
import scipy.sparse as sp

from rockfrac import threads
from rockfrac.case.build import build
from rockfrac.case.schema import load_case
from rockfrac.elements import plastic_solid
from rockfrac.elements.plastic_solid import DruckerPragerSolid, dp_element
from rockfrac.elements.solid import ElasticSolid, SolidGeometry
from rockfrac.fem.assembly import Pattern, scatter_matrix
from rockfrac.fem.kinematics import b_matrix, elastic_assemble, elastic_blocks, strains, voigt_index
from rockfrac.fem.reference import QUAD4
from rockfrac.laws import drucker_prager as dp
from rockfrac.laws.bifurcation import _ratio, localization_at, min_ratios_plane_strain, screen_plane_strain
from rockfrac.laws.drucker_prager_params import N_STATE, S_MODE, DruckerPrager
from rockfrac.laws.elastic import elasticity

ROOT = Path(__file__).resolve().parents[1]
LAW = DruckerPrager(E=1.5e7, nu=0.3, beta=0.480385, b=0.321597, kappa0=7532.54, H=43802.9)


def distorted_quads(n, seed=0):
    rng = np.random.default_rng(seed)
    h = 1.0 / n
    x, y = np.meshgrid(np.linspace(0, 1, n + 1), np.linspace(0, 1, n + 1))
    nodes = np.column_stack([x.ravel(), y.ravel()])
    inner = (nodes > 0).all(axis=1) & (nodes < 1).all(axis=1)
    nodes[inner] += rng.uniform(-0.2 * h, 0.2 * h, (inner.sum(), 2))
    i, j = np.meshgrid(np.arange(n), np.arange(n))
    a = (j * (n + 1) + i).ravel()
    return nodes, np.column_stack([a, a + 1, a + n + 2, a + n + 1])


def test_fused_elastic_assembly_is_bitwise_the_blocks_and_scatter():
    nodes, cells = distorted_quads(30)
    geo = SolidGeometry(nodes, cells, QUAD4)
    d = elasticity(6e7, 0.2, 2)
    pattern = Pattern.build(2 * nodes.shape[0], [geo.dofs])
    assert pattern.slots[0].dtype == np.int32
    ref = np.zeros(pattern.nnz)
    scatter_matrix(ref, pattern.slots[0].astype(np.int64), elastic_blocks(geo.grads, geo.wdet, d))
    fast = np.zeros(pattern.nnz)
    elastic_assemble(geo.grads, geo.wdet, d, pattern.slots[0], fast)
    assert np.array_equal(fast, ref)
    assert np.abs(ref).max() > 1e6  # not a trivially zero matrix


def strains_for(n, seed=3):
    """Elastic, cone and apex points (plane strain, tension positive)."""
    rng = np.random.default_rng(seed)
    eps = np.zeros((n, 6))
    k = np.arange(n) % 3
    eps[:, 0] = np.where(k == 0, 1e-5, np.where(k == 1, 6e-3, 5e-3)) * rng.uniform(0.5, 1.0, n)
    eps[:, 1] = np.where(k == 0, -1e-5, np.where(k == 1, -1e-2, 5e-3)) * rng.uniform(0.5, 1.0, n)
    eps[:, 3] = np.where(k == 2, 0.0, 1e-3 * rng.uniform(-1, 1, n))
    return eps


def test_return_map_points_equal_the_point_by_point_reference():
    n = 300
    p = LAW.as_array()
    eps = strains_for(n)
    s_old = np.zeros((n, N_STATE))
    s_old[:, 6] = 1e-4  # some accumulated gamma
    sig, c, s_new = np.empty((n, 6)), np.empty((n, 6, 6)), np.empty((n, N_STATE))
    st = np.empty(n, dtype=np.int64)
    dp.return_map_points(eps, s_old, p, sig, c, s_new, st)
    assert set(np.unique(st)) == {0, 1, 2}  # elastic, cone and apex all exercised
    for i in range(n):
        sr, cr, snr = np.empty(6), np.empty((6, 6)), np.empty(N_STATE)
        assert dp.return_map(eps[i], s_old[i], p, sr, cr, snr) == st[i]
        assert np.array_equal(sr, sig[i]) and np.array_equal(cr, c[i]) and np.array_equal(snr, s_new[i])


def solid_state(n_side=12):
    nodes, cells = distorted_quads(n_side)
    solid = DruckerPragerSolid(nodes * 0.04, cells, QUAD4, LAW)
    u = np.zeros(2 * nodes.shape[0])
    x, y = nodes[:, 0], nodes[:, 1]  # strains grow from zero at x = 0: elastic and plastic cells
    u[0::2] = 4e-3 * 0.04 * x ** 3
    u[1::2] = -8e-3 * 0.04 * y * x ** 2
    return solid, u


@nb.njit
def _reference_blocks(grads, wdet, ue, s_old, p, s_new, sigma, fe, ke, status):
    for e in range(grads.shape[0]):
        status[e] = dp_element(grads[e], wdet[e], ue[e], s_old[e], p, s_new[e], sigma[e], fe[e], ke[e])


def test_drucker_prager_cells_fast_equal_reference_and_numpy():
    solid, u = solid_state()
    ev = solid.evaluate(u, u)
    ue = np.ascontiguousarray(u[solid.dofs])
    n_el, nd = solid.dofs.shape
    fe, ke = np.empty((n_el, nd)), np.empty((n_el, nd, nd))
    st = np.empty(n_el, dtype=np.int64)
    s_new, sig = np.empty_like(solid.trial), np.empty_like(solid.trial_sigma)
    _reference_blocks(solid.grads, solid.wdet, ue, solid.state, solid.p, s_new, sig, fe, ke, st)
    assert np.array_equal(ev.fe, fe) and np.array_equal(ev.ke, ke) and np.array_equal(solid.trial, s_new)
    assert 0.3 < np.mean(solid.trial[..., S_MODE] > 0) < 1.0  # elastic and plastic cells both present
    # plain NumPy: strains, point return maps, sum_q w B^T sigma and w B^T C B
    eps = strains(solid.grads, ue).reshape(-1, 6)
    npt = eps.shape[0]
    sg, cc, sn = np.empty((npt, 6)), np.empty((npt, 6, 6)), np.empty((npt, N_STATE))
    dp.return_map_points(eps, solid.state.reshape(npt, -1), solid.p, sg, cc, sn, np.empty(npt, dtype=np.int64))
    idx = voigt_index(2)
    b = np.empty((n_el, 4, 3, nd))
    for e in range(n_el):
        for q in range(4):
            b_matrix(solid.grads[e, q], b[e, q])
    w = solid.wdet
    c3 = cc.reshape(n_el, 4, 6, 6)[:, :, idx][:, :, :, idx]
    fe_np = np.einsum("eq,eqki,eqk->ei", w, b, sg.reshape(n_el, 4, 6)[:, :, idx])
    ke_np = np.einsum("eq,eqki,eqkl,eqlj->eij", w, b, c3, b)
    scale = np.abs(ke_np).max()
    assert np.abs(ev.ke - ke_np).max() <= 1e-12 * scale
    assert np.abs(ev.fe - fe_np).max() <= 1e-12 * np.abs(fe_np).max()


def test_serial_and_two_threads_agree(monkeypatch):
    if nb.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("one thread only")
    monkeypatch.setattr(threads, "FORCE", "parallel")  # 256 cells: the prange version on the threads set below
    solid, u = solid_state(16)
    saved = nb.get_num_threads()
    try:
        nb.set_num_threads(1)
        a = solid.evaluate(u, u)
        trial1 = solid.trial.copy()
        nb.set_num_threads(2)
        b = solid.evaluate(u, u)
    finally:
        nb.set_num_threads(saved)
    assert np.array_equal(a.ke, b.ke) and np.array_equal(a.fe, b.fe) and np.array_equal(trial1, solid.trial)


def grains_case(n_grains=6, size=0.004, steps=40):
    case = load_case(ROOT / "examples" / "grains" / "grains.toml")
    mesh = case.mesh.model_copy(update={"n_grains": n_grains, "element_size": size})
    loading = case.loading.model_copy(update={"axial_steps": steps})
    out = case.output.model_copy(update={"vtk": False, "points": False, "checkpoint_every": None})
    return case.model_copy(update={"mesh": mesh, "loading": loading, "output": out})


def coo_assembly(model, u, f_ext):
    """The residual and tangent by plain SciPy COO sums of the groups' element arrays."""
    n = model.n_dofs
    rows, cols, vals = [], [], []
    f = np.zeros(n)
    for g in model.groups:
        if g.constant:
            ke = g.ke
            fe = np.einsum("eij,ej->ei", ke, u[g.dofs])
        else:
            saved = getattr(g, "reuse_buffers", None)
            if saved is not None:
                g.reuse_buffers = False
            ev = g.evaluate(u, u)
            if saved is not None:
                g.reuse_buffers = saved
            fe, ke = ev.fe, ev.ke
        nd = g.dofs.shape[1]
        rows.append(np.repeat(g.dofs, nd, axis=1).ravel())
        cols.append(np.tile(g.dofs, (1, nd)).ravel())
        vals.append(ke.ravel())
        np.add.at(f, g.dofs.ravel(), fe.ravel())
    k = sp.coo_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(n, n))
    return f - f_ext, k.tocsr()


def test_engine_assembly_equals_scipy_coo_on_grains():
    built = build(grains_case())
    model = built.model
    assert any(isinstance(g, ElasticSolid) for g in model.groups)
    assert any(isinstance(g, DruckerPragerSolid) for g in model.groups)
    rng = np.random.default_rng(5)
    u = np.zeros(model.n_dofs)
    x = built.mesh.nodes
    u[0 : 2 * x.shape[0] : 2] = 2e-3 * x[:, 0]  # lateral expansion, axial shortening: plastic matrix
    u[1 : 2 * x.shape[0] : 2] = -8e-3 * x[:, 1]
    u[2 * x.shape[0] :] = rng.uniform(-1e3, 1e3, model.n_dofs - 2 * x.shape[0])  # multipliers
    f_ext = rng.uniform(-1.0, 1.0, model.n_dofs)
    model.begin_step()
    asm = model.assemble(u, u, f_ext)
    r_ref, k_ref = coo_assembly(model, u, f_ext)
    plastic = [g for g in model.groups if isinstance(g, DruckerPragerSolid)]
    assert np.mean([np.mean(g.trial[..., S_MODE] > 0) for g in plastic]) > 0.1
    diff = abs(asm.matrix - k_ref)
    assert diff.max() <= 1e-12 * abs(k_ref).max()
    assert np.abs(asm.residual - r_ref).max() <= 1e-12 * np.abs(r_ref).max()


def run_history(case, steps):
    from rockfrac.runner import history_row
    from rockfrac.solve import stepping
    from rockfrac.solve.linear import make_solver
    from rockfrac.solve.newton import NewtonOptions
    from rockfrac.solve.stepping import SteppingOptions, StopRun

    built = build(case)
    sol = case.solver
    newton = NewtonOptions(sol.max_iterations, sol.tol_residual, sol.tol_energy,
                           force_scale=1e-6 * max(m.E for m in case.material_list) * case.mesh.width)
    rows = []

    def on_step(info):
        rows.append((history_row(built, info, None)["F_axial"], info.newton.iterations, info.u.copy()))
        if len(rows) >= steps:
            raise StopRun("enough")

    try:
        stepping.run_stages(built.model, built.stages, make_solver("superlu"), newton,
                            SteppingOptions(cutback=sol.cutback, min_step=sol.min_step), on_step)
    except StopRun:
        pass
    return rows, built


def test_grains_history_unchanged_with_reference_paths(monkeypatch):
    case = grains_case(steps=8)
    fast, built = run_history(case, 4)
    plastic = [g for g in built.model.groups if isinstance(g, DruckerPragerSolid)]
    assert max(g.plastic_fraction() for g in plastic) > 0.0  # the matrix yields within these steps
    # reference paths: the elastic blocks scattered, fresh element arrays, allocating DP loop
    monkeypatch.setattr(ElasticSolid, "assemble_constant",
                        lambda self, data, slots: scatter_matrix(data, slots, self.ke))
    monkeypatch.setattr(DruckerPragerSolid, "reuse_buffers", property(lambda s: False, lambda s, v: None))
    monkeypatch.setattr(plastic_solid, "dp_blocks", _reference_blocks)
    ref, _ = run_history(case, 4)
    assert len(fast) == len(ref) >= 3
    for (fa, ia, ua), (fb, ib, ub) in zip(fast, ref):
        assert ia == ib and fa == fb and np.array_equal(ua, ub)


def cone_stresses(n, seed=7):
    """Stresses on the Drucker-Prager cone of LAW (compressive, sheared), by return maps."""
    eps = strains_for(3 * n, seed)[1::3][:n]
    sig, c, s_new = np.empty((n, 6)), np.empty((n, 6, 6)), np.empty((n, N_STATE))
    st = np.empty(n, dtype=np.int64)
    dp.return_map_points(eps, np.zeros((n, N_STATE)), LAW.as_array(), sig, c, s_new, st)
    assert (st == 1).all()
    return sig


def test_batched_bifurcation_minima_equal_the_one_point_search():
    sig = cone_stresses(40)
    fast = min_ratios_plane_strain(LAW, sig)
    ref = np.array([localization_at(LAW, s).min_ratio for s in sig])
    assert np.array_equal(fast, ref)


@nb.njit
def _reference_screen(sigma, p, ce, n_sweep):
    out = np.empty(sigma.shape[0])
    for i in range(sigma.shape[0]):
        c = dp.perfectly_plastic_tangent(ce, dp.yield_gradient(sigma[i], p), dp.potential_gradient(sigma[i], p))
        best = np.inf
        nrm = np.zeros(3)
        for k in range(n_sweep):
            t = np.pi * k / n_sweep
            nrm[0] = math.cos(t)
            nrm[1] = math.sin(t)
            best = min(best, _ratio(c, ce, nrm))
        out[i] = best
    return out


def test_screen_equals_the_point_by_point_sweep():
    sig = cone_stresses(50)
    p, ce = LAW.as_array(), LAW.elastic_matrix()
    assert np.array_equal(screen_plane_strain(sig, p, ce, 90), _reference_screen(sig, p, ce, 90))


def test_sparse_acoustic_tensor_equals_the_dense_product():
    from rockfrac.laws.bifurcation import _acoustic, _acoustic_dense

    rng = np.random.default_rng(11)
    for c in (LAW.elastic_matrix(), rng.normal(size=(6, 6)) * 1e7):
        for _ in range(50):
            n = rng.normal(size=3)
            n /= np.linalg.norm(n)
            if rng.uniform() < 0.5:
                n[2] = 0.0
            a, b = np.empty((3, 3)), np.empty((3, 3))
            _acoustic(c, n, a)
            _acoustic_dense(c, n, b)
            assert np.array_equal(a, b)


# the plane-strain search as it was (dense acoustic tensor, work arrays per call): the reference
from rockfrac.laws.bifurcation import _acoustic_dense, _cofactor  # noqa: E402


@nb.njit
def _det_grad_ref(c, n, grad):
    a = np.empty((3, 3))
    cof = np.empty((3, 3))
    _acoustic_dense(c, n, a)
    det = _cofactor(a, cof)
    npe = np.empty(3)
    nme = np.empty(3)
    em = np.empty((3, 3))
    ep = np.empty((3, 3))
    for m in range(3):
        for i in range(3):
            npe[i] = n[i]
            nme[i] = n[i]
        npe[m] += 1.0
        nme[m] -= 1.0
        _acoustic_dense(c, npe, ep)  # A is quadratic in n: A(n + e_m) - A(n - e_m) = 2 dA/dn_m exactly
        _acoustic_dense(c, nme, em)
        acc = 0.0
        for i in range(3):
            for k in range(3):
                acc += cof[i, k] * 0.5 * (ep[i, k] - em[i, k])
        grad[m] = acc
    return det


@nb.njit
def _ratio_grad_ref(c, ce, n, grad):
    g1 = np.empty(3)
    g2 = np.empty(3)
    d1 = _det_grad_ref(c, n, g1)
    d2 = _det_grad_ref(ce, n, g2)
    for m in range(3):
        grad[m] = (g1[m] * d2 - d1 * g2[m]) / (d2 * d2)
    return d1 / d2


@nb.njit
def _ratio_ref(c, ce, n):
    a = np.empty((3, 3))
    cof = np.empty((3, 3))
    _acoustic_dense(c, n, a)
    d1 = _cofactor(a, cof)
    _acoustic_dense(ce, n, a)
    return d1 / _cofactor(a, cof)


@nb.njit
def _dtheta_ref(c, ce, t):
    n = np.array([math.cos(t), math.sin(t), 0.0])
    g = np.empty(3)
    _ratio_grad_ref(c, ce, n, g)
    return -math.sin(t) * g[0] + math.cos(t) * g[1]


@nb.njit
def _plane_strain_minima_ref(c, ce, n_sweep, theta_out, ratio_out):
    h = math.pi / n_sweep
    r = np.empty(n_sweep)
    for i in range(n_sweep):
        t = i * h
        r[i] = _ratio_ref(c, ce, np.array([math.cos(t), math.sin(t), 0.0]))
    count = 0
    for i in range(n_sweep):
        if not (r[i] < r[(i - 1) % n_sweep] and r[i] <= r[(i + 1) % n_sweep]):
            continue
        lo, hi = i * h - h, i * h + h
        t = i * h
        if _dtheta_ref(c, ce, lo) < 0.0 and _dtheta_ref(c, ce, hi) > 0.0:
            for _ in range(200):
                mid = 0.5 * (lo + hi)
                if mid <= lo or mid >= hi:
                    break
                if _dtheta_ref(c, ce, mid) > 0.0:
                    hi = mid
                else:
                    lo = mid
            t = 0.5 * (lo + hi)
        t = t % math.pi
        theta_out[count] = t
        ratio_out[count] = _ratio_ref(c, ce, np.array([math.cos(t), math.sin(t), 0.0]))
        count += 1
    return count


@nb.njit
def _reference_minima(sigma, p, ce, n_sweep, th, rr, count):
    for i in range(sigma.shape[0]):
        c = dp.perfectly_plastic_tangent(ce, dp.yield_gradient(sigma[i], p), dp.potential_gradient(sigma[i], p))
        count[i] = _plane_strain_minima_ref(c, ce, n_sweep, th[i], rr[i])


def test_plane_strain_minima_equal_the_dense_search():
    from rockfrac.laws.bifurcation import N_SWEEP, minima_plane_strain

    sig = cone_stresses(30)
    p, ce = LAW.as_array(), LAW.elastic_matrix()
    th, rr = np.zeros((30, N_SWEEP)), np.zeros((30, N_SWEEP))
    cnt = np.zeros(30, dtype=np.int64)
    _reference_minima(sig, p, ce, N_SWEEP, th, rr, cnt)
    th2, rr2 = np.zeros((30, 16)), np.zeros((30, 16))
    cnt2 = np.zeros(30, dtype=np.int64)
    minima_plane_strain(sig, p, ce, N_SWEEP, th2, rr2, cnt2)
    assert np.array_equal(cnt, cnt2) and cnt.min() >= 2  # the conjugate pair at least
    for i in range(30):
        assert np.array_equal(th[i, : cnt[i]], th2[i, : cnt[i]]) and np.array_equal(rr[i, : cnt[i]], rr2[i, : cnt[i]])


def _rotate_back(r, t, d, tg, dg):
    """Reference: global traction tg = R^T t and tangent dg = R^T d R (the loops the kernel had)."""
    for i in range(2):
        tg[i] = r[0, i] * t[0] + r[1, i] * t[1]
    for i in range(2):
        for j in range(2):
            s = 0.0
            for a in range(2):
                for b in range(2):
                    s += r[a, i] * d[a, b] * r[b, j]
            dg[i, j] = s


def _pair_blocks(w, tg, dg, fe, ke):
    """Reference: force and stiffness of one node pair, dofs (minus x, minus y, plus x, plus y)."""
    for i in range(2):
        fe[i] = -w * tg[i]
        fe[2 + i] = w * tg[i]
        for j in range(2):
            k = w * dg[i, j]
            ke[i, j] = k
            ke[i, 2 + j] = -k
            ke[2 + i, j] = -k
            ke[2 + i, 2 + j] = k


def test_ep_points_equal_the_point_by_point_law_and_blocks():
    """ep_points on scalars (no temporaries) is bit for bit ep_update + rotation + pair blocks."""
    from rockfrac.elements import cse
    from rockfrac.laws.cohesive import ep_update
    from rockfrac.laws.cohesive_params import N_STATE, S_MODE, S_TN, S_TT, CohesiveLaw

    rng = np.random.default_rng(7)
    n = 400
    law = CohesiveLaw(GfI=1e4, GfII=1e4, chi_p=15680.0, chi_r=0.0, c_p=9053.0, c_r=0.0, phi_p=0.5236,
                      phi_r=0.0, psi_p=0.087, alpha_chi=2e3, alpha_c=2e3, alpha_phi=9e2, alpha_psi=9e2,
                      kn=1e9, kt=1e9, work_rule="trapezoidal")
    p = law.as_array()
    ang = rng.uniform(0, np.pi, n)
    frame = np.empty((n, 2, 2))
    frame[:, 0, 0], frame[:, 0, 1] = np.cos(ang), np.sin(ang)
    frame[:, 1, 0], frame[:, 1, 1] = -np.sin(ang), np.cos(ang)
    weight = rng.uniform(0.5e-3, 1.5e-3, n)
    djump = rng.uniform(-3e-5, 3e-5, (n, 2)) * (rng.uniform(size=(n, 1)) < 0.5)  # half elastic-small
    djump += rng.uniform(-1e-7, 1e-7, (n, 2))
    djump[:20] = 0.0  # committed plastic points at zero increment keep their state
    s_old = np.zeros((n, N_STATE))
    s_old[:20, S_MODE] = 1.0
    s_old[:20, S_TT] = 10.0
    d_old = rng.uniform(size=(n, 2, 2))
    s_new, d_new = np.empty_like(s_old), np.empty_like(d_old)
    fe, ke, status = np.empty((n, 4)), np.empty((n, 4, 4)), np.empty(n, dtype=np.int64)
    cse.ep_points(frame, weight, djump, s_old, d_old, p, s_new, d_new, fe, ke, status)
    assert 100 < np.sum(status == 1) < n - 100 and np.all(status >= 0)
    for i in range(20, n):
        r, j = frame[i], djump[i]
        du = np.array([r[0, 0] * j[0] + r[0, 1] * j[1], r[1, 0] * j[0] + r[1, 1] * j[1]])
        s1, d1 = np.empty(N_STATE), np.empty((2, 2))
        assert ep_update(du, s_old[i], p, s1, d1) == status[i]
        tg, dg = np.empty(2), np.empty((2, 2))
        _rotate_back(frame[i], s1[S_TT:S_TN + 1].copy(), d1, tg, dg)
        f1, k1 = np.empty(4), np.empty((4, 4))
        _pair_blocks(weight[i], tg, dg, f1, k1)
        np.testing.assert_array_equal(s_new[i], s1)
        np.testing.assert_array_equal(d_new[i], d1)
        np.testing.assert_array_equal(fe[i], f1)
        np.testing.assert_array_equal(ke[i], k1)
    np.testing.assert_array_equal(d_new[:20], d_old[:20])


def test_rp_points_equal_the_point_by_point_law_and_blocks():
    """rp_points on scalars is bit for bit the law's return from lambda + rotation + the blocks of eq. 32-33."""
    from rockfrac.elements import cse
    from rockfrac.laws.cohesive import START_NONE, return_map_from
    from rockfrac.laws.cohesive_params import N_STATE, S_TN, S_TT, CohesiveLaw

    rng = np.random.default_rng(8)
    n, aug = 300, 1e9
    law = CohesiveLaw(GfI=1e4, GfII=1e4, chi_p=15680.0, chi_r=0.0, c_p=9053.0, c_r=0.0, phi_p=0.5236,
                      phi_r=0.0, psi_p=0.087, alpha_chi=2e3, alpha_c=2e3, alpha_phi=9e2, alpha_psi=9e2)
    p = law.as_array()
    ang = rng.uniform(0, np.pi, n)
    frame = np.empty((n, 2, 2))
    frame[:, 0, 0], frame[:, 0, 1] = np.cos(ang), np.sin(ang)
    frame[:, 1, 0], frame[:, 1, 1] = -np.sin(ang), np.cos(ang)
    weight = rng.uniform(0.5e-3, 1.5e-3, n)
    lam = rng.uniform(-100.0, 100.0, (n, 2))
    djump = rng.uniform(-1e-12, 1e-12, (n, 2))
    big = rng.uniform(size=n) < 0.5
    djump[big] = np.column_stack([rng.uniform(-4e-5, 4e-5, big.sum()), rng.uniform(0, 2e-6, big.sum())])
    s_old, d_old = np.zeros((n, N_STATE)), np.zeros((n, 2, 2))
    s_new, d_new = np.empty_like(s_old), np.empty_like(d_old)
    fe, ke = np.empty((n, 6)), np.empty((n, 6, 6))
    status, switched = np.empty(n, dtype=np.int64), np.empty(n, dtype=np.int64)
    cse.rp_points(frame, weight, djump, lam, aug, np.zeros(n), np.zeros(n, dtype=bool), s_old, d_old,
                  np.zeros(n), p, s_new, d_new, fe, ke, status, switched)
    assert 50 < np.sum(status == 1) < n - 50
    comp = np.array([1.0 / aug, 1.0 / aug])
    for i in range(n):
        r, j, w = frame[i], djump[i], weight[i]
        h = np.array([r[0, 0] * j[0] + r[0, 1] * j[1], r[1, 0] * j[0] + r[1, 1] * j[1]])
        s_lam = s_old[i].copy()
        s_lam[S_TT] = r[0, 0] * lam[i, 0] + r[0, 1] * lam[i, 1]
        s_lam[S_TN] = r[1, 0] * lam[i, 0] + r[1, 1] * lam[i, 1]
        s1, d1 = np.empty(N_STATE), np.empty((2, 2))
        assert return_map_from(h, s_lam, s_old[i, S_TT:S_TN + 1].copy(), START_NONE, comp, p, s1, d1) == status[i]
        tg, dg = np.empty(2), np.empty((2, 2))
        _rotate_back(r, s1[S_TT:S_TN + 1].copy(), d1, tg, dg)
        f1, k1 = np.empty(6), np.empty((6, 6))
        _pair_blocks(w, tg, dg, f1[:4], k1)
        for a in range(2):
            f1[4 + a] = w * (tg[a] - lam[i, a])
            for b in range(2):
                kab = w * dg[a, b]
                k1[a, 4 + b] = -kab / aug
                k1[2 + a, 4 + b] = kab / aug
                k1[4 + a, b] = -kab
                k1[4 + a, 2 + b] = kab
                k1[4 + a, 4 + b] = kab / aug - (w if a == b else 0.0)
        np.testing.assert_array_equal(s_new[i], s1)
        np.testing.assert_array_equal(d_new[i], d1)
        np.testing.assert_array_equal(fe[i], f1)
        np.testing.assert_array_equal(ke[i], k1)
