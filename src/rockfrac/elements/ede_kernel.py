"""Compiled kernel of the embedded strong discontinuity element (AES, paper Sect. 5; EDE_NOTES).

A localized element carries a surface through its centre with normal n and tangent t (frozen at
bifurcation), active (+ side) nodes and f_S = sum of their N_a, and a jump [[u]] = J (global
frame) that grows as dJ = m d(zeta), m = s cos(psi) t + sin(psi) n, s = sign of the shear. The
bulk is frozen at bifurcation (plastic strain eps_p held, as in the paper's Tahoe element): at
every Gauss point sigma = Ce : (B d - eps_p - sym(J x grad f_S)). The local equation (27) uses
the volume averages q = <t.sigma.n>, P = <n.sigma.n>:

    r = s q + tan(phi) min(P, 0) - c = 0   (the yield function (21) on the averaged traction),

with c, phi, psi of gamma = gamma_n + cos(psi) dzeta (Sect. 4.1). The trial check (Sect. 5.3) is
r at dzeta = 0 with the committed strengths; if positive the cell slides and dzeta is an unknown
of the Newton iteration, eliminated per cell by static condensation:

    K = K_dd - g h^T / k,  f = f_int - g r / k,  g = df/d dzeta, h = dr/dd, k = dr/d dzeta,

and recovered after the global solve as d dzeta = -(r + h . dd) / k (EDE_NOTES; Tahoe). dzeta is
not solved at fixed nodes: with grad f_S not along n, sliding at fixed nodes can relax the
normal compression faster than the shear (k > 0), a local instability the coupled problem does
not have. For the same reason the trial check is not repeated on iterates of a sliding cell
(their nodes already carry the slide): a cell keeps sliding while its updated dzeta is positive,
and is rigid (dzeta = 0) when it is not and its trial is inside the surface (dzeta >= 0, r <= 0,
dzeta r = 0 at convergence).

EDE state slots per element (float array, N_E): see the E_* constants.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from rockfrac.compiled import inner
from rockfrac.elements.plastic_solid import (
    dp_element_into,
    element_scratch,
    integrate_point,
    n_chunks,
    point_strain,
)
from rockfrac.fem.kinematics import b_matrix
from rockfrac.laws.drucker_prager import elastic_matrix as dp_elastic_matrix
from rockfrac.laws.drucker_prager import moduli as dp_moduli
from rockfrac.laws.drucker_prager_params import S_MODE
from rockfrac.laws.mohr_coulomb_softening import gamma_of, strengths
from rockfrac.threads import parallel_kernel

E_LOC = 0  # 1 once localized
E_N = 1  # normal n, slots 1..3
E_T = 4  # tangent t, slots 4..6 ((t, n) right-handed in the x-y plane)
E_CP = 7  # peak cohesion c_p [Pa] (eq. 28)
E_GAMMA = 8  # gamma [m]
E_ZETA = 9  # accumulated zeta [m]
E_DZETA = 10  # dzeta of the step [m]
E_J = 11  # jump vector [[u]] (global frame) [m], slots 11..13
E_Q = 14  # averaged shear traction q = <t.sigma.n> [Pa]
E_P = 15  # averaged normal traction P = <n.sigma.n> [Pa]
E_MODE = 16  # 0 rigid (constrained), 1 sliding (plastic) in the step
E_SIGN = 17  # s, the slip sense along t
E_MT = 18  # dJ / d dzeta of the iterate, slots 18..20 (path following)
N_E = 21

K_FLOOR = 1e-2  # smallest |dr/d dzeta| relative to the scale of its terms (see _localized)

ST_OK = 0
ST_NOT_UNIQUE = -2  # dr/d dzeta = 0: the jump does not enter the local equation
ST_DP_FAIL = -3


@inner
def _sym_jump(v, g, e6):
    """Voigt strain (engineering shear) of sym(v x g)."""
    e6[0] = v[0] * g[0]
    e6[1] = v[1] * g[1]
    e6[2] = v[2] * g[2]
    e6[3] = v[0] * g[1] + v[1] * g[0]
    e6[4] = v[1] * g[2] + v[2] * g[1]
    e6[5] = v[0] * g[2] + v[2] * g[0]


@inner
def _traction_weights(a, b, w6):
    """w6 such that w6 . sigma6 = a . sigma . b (stress-like Voigt)."""
    w6[0] = a[0] * b[0]
    w6[1] = a[1] * b[1]
    w6[2] = a[2] * b[2]
    w6[3] = a[0] * b[1] + a[1] * b[0]
    w6[4] = a[1] * b[2] + a[2] * b[1]
    w6[5] = a[0] * b[2] + a[2] * b[0]


@inner
def _dot6(a, b):
    s = 0.0
    for i in range(6):
        s += a[i] * b[i]
    return s


@inner
def _localized(grads, wdet, ue, eps_p, ce, gradf, e_old, law, dz, slide, stick, sigma, e_new, fe, ke, h_vec):
    """One localized cell at the jump increment dz (module doc): stresses, condensed fe and ke,
    new EDE state; h_vec (nd,) receives dr/dd. Returns (status, r, k = dr/d dzeta, dz used)."""
    n_qp, n_nodes, dim = grads.shape
    nd = n_nodes * dim
    nv = 3 if dim == 2 else 6
    idx = np.array([0, 1, 3]) if dim == 2 else np.arange(6)
    n = e_old[E_N:E_N + 3].copy()
    t = e_old[E_T:E_T + 3].copy()
    jn = e_old[E_J:E_J + 3].copy()
    c_p, gamma_n = e_old[E_CP], e_old[E_GAMMA]
    w_tn = np.empty(6)
    w_nn = np.empty(6)
    _traction_weights(t, n, w_tn)
    _traction_weights(n, n, w_nn)
    vol = 0.0
    for q in range(n_qp):
        vol += wdet[q]
    # trial stresses (dzeta = 0), their averages, and the responses to unit jumps along e_k
    b = np.empty((nv, nd))
    eps6 = np.empty(6)
    e6 = np.empty(6)
    s6 = np.empty(6)
    sig_tr = np.empty((n_qp, 6))
    resp = np.zeros((n_qp, 3, 6))  # Ce : sym(e_k x grad f_S) per Gauss point
    q_tr = 0.0
    p_tr = 0.0
    a_q = np.zeros(3)  # <t . resp_k . n>
    a_p = np.zeros(3)  # <n . resp_k . n>
    ek = np.zeros(3)
    for q in range(n_qp):
        b_matrix(grads[q], b)
        point_strain(b, ue, idx, eps6)
        _sym_jump(jn, gradf[q], e6)
        for i in range(6):
            eps6[i] -= eps_p[q, i] + e6[i]
        for i in range(6):
            acc = 0.0
            for j in range(6):
                acc += ce[i, j] * eps6[j]
            sig_tr[q, i] = acc
        w = wdet[q] / vol
        q_tr += w * _dot6(w_tn, sig_tr[q])
        p_tr += w * _dot6(w_nn, sig_tr[q])
        for k in range(3):
            ek[:] = 0.0
            ek[k] = 1.0
            _sym_jump(ek, gradf[q], e6)
            for i in range(6):
                acc = 0.0
                for j in range(6):
                    acc += ce[i, j] * e6[j]
                resp[q, k, i] = acc
            a_q[k] += w * _dot6(w_tn, resp[q, k])
            a_p[k] += w * _dot6(w_nn, resp[q, k])
    s = 1.0 if q_tr >= 0.0 else -1.0
    c_n, tphi_n, _, _, _, _ = strengths(gamma_n, c_p, law)
    f_tr = s * q_tr + tphi_n * min(p_tr, 0.0) - c_n
    scale = max(c_p, abs(q_tr), abs(p_tr), 1.0)
    plastic = (slide or f_tr > 1.0e-12 * scale) and not stick
    if not plastic:
        dz = 0.0
    dz = max(dz, 0.0)
    gamma, dgam = gamma_of(dz, gamma_n, law)
    c, tphi, psi, dc, dtphi, dpsi = strengths(gamma, c_p, law)
    cp, sp = math.cos(psi), math.sin(psi)
    m = np.zeros(3)
    mt = np.zeros(3)  # dJ / d dzeta
    for k in range(3):
        m[k] = s * cp * t[k] + sp * n[k]
        mt[k] = m[k] + dz * (-s * sp * t[k] + cp * n[k]) * dpsi * dgam
    if not plastic:
        m[:] = 0.0
    qv = q_tr - dz * (a_q[0] * m[0] + a_q[1] * m[1] + a_q[2] * m[2])
    pv = p_tr - dz * (a_p[0] * m[0] + a_p[1] * m[1] + a_p[2] * m[2])
    comp = 1.0 if pv < 0.0 else 0.0
    r = s * qv + tphi * min(pv, 0.0) - c
    t_q = -s * (a_q[0] * mt[0] + a_q[1] * mt[1] + a_q[2] * mt[2])
    t_p = -tphi * comp * (a_p[0] * mt[0] + a_p[1] * mt[1] + a_p[2] * mt[2])
    t_s = (dtphi * min(pv, 0.0) - dc) * dgam
    kz = t_q + t_p + t_s
    # dr/d dzeta is a difference of large terms (shear unloading, normal relaxation, softening) and
    # crosses zero during softening; eliminating dzeta with k ~ 0 is ill-conditioned, so |k| is
    # bounded below by K_FLOOR of its terms' scale: the dzeta update becomes a damped Newton step
    # (r -> 0 is still required at convergence, so the converged state is unchanged)
    floor = K_FLOOR * (abs(t_q) + abs(t_p) + abs(t_s))
    if abs(kz) < floor:
        kz = floor if kz >= 0.0 else -floor
    status = ST_OK
    if plastic and not abs(kz) > 1.0e-30:
        status = ST_NOT_UNIQUE
    # stresses, force, tangent; g = dfe/d dzeta, h = dr/dd
    fe[:] = 0.0
    ke[:, :] = 0.0
    h_vec[:] = 0.0
    cb = np.empty((nv, nd))
    g_vec = np.zeros(nd)
    hw = np.empty(6)
    for i in range(6):
        hw[i] = s * w_tn[i] + tphi * comp * w_nn[i]
    hc = np.empty(6)  # Hhat : Ce
    for j in range(6):
        acc = 0.0
        for i in range(6):
            acc += hw[i] * ce[i, j]
        hc[j] = acc
    for q in range(n_qp):
        b_matrix(grads[q], b)
        w = wdet[q]
        for i in range(6):
            s6[i] = sig_tr[q, i] - dz * (resp[q, 0, i] * m[0] + resp[q, 1, i] * m[1] + resp[q, 2, i] * m[2])
            sigma[q, i] = s6[i]
        integrate_point(b, w, s6, ce, idx, fe, ke, cb)
        for a in range(nd):
            acc_g = 0.0
            acc_h = 0.0
            for k in range(nv):
                dsig = resp[q, 0, idx[k]] * mt[0] + resp[q, 1, idx[k]] * mt[1] + resp[q, 2, idx[k]] * mt[2]
                acc_g -= b[k, a] * dsig
                acc_h += hc[idx[k]] * b[k, a]
            g_vec[a] += w * acc_g
            h_vec[a] += w * acc_h / vol
    if plastic and status == ST_OK:
        for i in range(nd):
            fe[i] -= g_vec[i] * r / kz
            for j in range(nd):
                ke[i, j] -= g_vec[i] * h_vec[j] / kz
    for k in range(e_old.shape[0]):  # a loop, not a slice copy: no shape-error path to compile
        e_new[k] = e_old[k]
    e_new[E_GAMMA] = gamma
    e_new[E_ZETA] = e_old[E_ZETA] + dz
    e_new[E_DZETA] = dz
    for k in range(3):
        e_new[E_J + k] = jn[k] + dz * m[k]
    e_new[E_Q] = qv
    e_new[E_P] = pv
    e_new[E_MODE] = 1.0 if plastic else 0.0
    e_new[E_SIGN] = s
    for k in range(3):
        e_new[E_MT + k] = mt[k] if plastic else 0.0
    if not plastic:
        return status, (f_tr if stick else 0.0), 0.0, dz  # a stuck cell reports its trial yield value
    return status, r, kz, dz


@parallel_kernel(cost=1.2e-6)  # s per item, one thread (benchmarks/thread_rule.py)
def ede_blocks(grads, wdet, ue, dp_old, dp_p, ce, e_old, gradf, law, dz, slide, stick, dp_new, sigma, e_new, fe,
               ke, status, r_out, k_out, h_out):
    """Drucker-Prager cells, and embedded-discontinuity cells where localized (module doc).

    grads (n_el, n_qp, n_nodes, dim), wdet (n_el, n_qp), ue (n_el, nd); dp_old/dp_new (n_el, n_qp,
    N_STATE) Drucker-Prager states (frozen once localized); ce (6, 6); e_old/e_new (n_el, N_E);
    gradf (n_el, n_qp, 3) grad f_S; law: Sect. 4.1 parameters; dz (n_el,) the jump increments of
    this iterate (updated in place where clipped); slide (n_el,) bool: the cell slides whatever its
    trial (it slid in the last iterate and its updated dzeta is positive, or it slid in the last
    step and this is the step's first iterate); stick (n_el,) bool: held rigid (active-set pinning of
    a chattering cell; r_out then returns its trial yield value). r_out, k_out
    (n_el,), h_out (n_el, nd): the local residual r, dr/d dzeta and dr/dd for the next update.
    """
    n = grads.shape[0]
    dp_k, dp_mu = dp_moduli(dp_p)
    dp_ce = dp_elastic_matrix(dp_p)
    m = n_chunks(n)
    for ch in nb.prange(m):
        scratch = element_scratch(grads.shape[2], grads.shape[3])
        for e in range(ch * n // m, (ch + 1) * n // m):
            _ede_cell(e, grads, wdet, ue, dp_old, dp_p, dp_k, dp_mu, dp_ce, scratch, ce, e_old, gradf, law, dz,
                      slide, stick, dp_new, sigma, e_new, fe, ke, status, r_out, k_out, h_out)


@inner
def _ede_cell(e, grads, wdet, ue, dp_old, dp_p, dp_k, dp_mu, dp_ce, scratch, ce, e_old, gradf, law, dz, slide, stick,
              dp_new, sigma, e_new, fe, ke, status, r_out, k_out, h_out):
    """Cell e of :func:`ede_blocks` (scratch: :func:`element_scratch`, used by its Drucker-Prager cells)."""
    r_out[e] = 0.0
    k_out[e] = 0.0
    if e_old[e, E_LOC] == 1.0:
        for q in range(dp_old.shape[1]):  # the bulk is frozen: plastic strain held, elastic updates
            for k in range(dp_old.shape[2]):
                dp_new[e, q, k] = dp_old[e, q, k]
        dp_new[e, :, S_MODE] = 0.0
        st, r, kz, dzu = _localized(grads[e], wdet[e], ue[e], dp_old[e, :, 0:6], ce, gradf[e], e_old[e],
                                    law, dz[e], slide[e], stick[e], sigma[e], e_new[e], fe[e], ke[e], h_out[e])
        status[e], r_out[e], k_out[e], dz[e] = st, r, kz, dzu
        return
    for k in range(e_old.shape[1]):
        e_new[e, k] = e_old[e, k]
    st = dp_element_into(grads[e], wdet[e], ue[e], dp_old[e], dp_p, dp_k, dp_mu, dp_ce, dp_new[e], sigma[e],
                         fe[e], ke[e], scratch)
    status[e] = ST_DP_FAIL if st < 0 else ST_OK
