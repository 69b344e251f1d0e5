"""The cohesive local problem of rockfrac.laws.cohesive: scaled residual rows, Jacobian, work rule."""

from __future__ import annotations

import math

from rockfrac.compiled import inner, kernel
from rockfrac.laws.cohesive_params import P_C_P, P_CHI_P, P_GF1, P_GF2, P_THETA
from rockfrac.laws.cohesive_surface import (
    _isv,
    _ratio,
    _sign,
    elastic_tolerance,
    strengths,
    yield_function,
)

K_RP_SCALE = 1.0e10  # [Pa/m] sets the jump-row scale s / K_RP_SCALE when C = 0 and du = 0

START_NONE = 0  # no start-of-flow traction: backward Euler work for this step
START_GIVEN = 1  # the given traction is where flow starts (a committed plastic point)
START_CROSSING = 2  # flow starts where T_old + a K^e du meets the old yield surface


# --------------------------------------------------------------------------------------------
# the local problem: scaled residual and analytic Jacobian
# --------------------------------------------------------------------------------------------


@kernel
def _scale(p):
    """Traction scale s = c_p + chi_p [Pa] of the scaled residual."""
    return max(p[P_C_P] + p[P_CHI_P], 1.0)


@inner
def _jump_rows(x, du, t_old, comp, wu, q, r, jac):
    """Rows 0-1: jump balance R_u [m] (eq. 31 / K; eq. 34 if C = 0) times wu [1/m]."""
    tt, dg = x[0], x[4]
    chi, c, tphi, tpsi, dchi, dc, dtphi, dtpsi = q
    a_g = c - chi * tpsi
    r_g = math.sqrt(tt * tt + a_g * a_g)
    u = _ratio(tt, r_g)  # g_t
    v = _ratio(a_g, r_g)
    dgt_dtt = _ratio(v * v, r_g)  # a_G^2 / r_G^3, 0 at a degenerate corner
    dgt_dag = -_ratio(u * v, r_g)  # -T_t a_G / r_G^3
    dag_den = dc - tpsi * dchi
    dag_des = dag_den - chi * dtpsi
    r[0] = wu * (du[0] - dg * u - comp[0] * (tt - t_old[0]))
    r[1] = wu * (du[1] - dg * tpsi - comp[1] * (x[1] - t_old[1]))
    jac[0, 0] = -wu * (comp[0] + dg * dgt_dtt)
    jac[0, 1] = 0.0
    jac[0, 2] = -wu * dg * dgt_dag * dag_den
    jac[0, 3] = -wu * dg * dgt_dag * dag_des
    jac[0, 4] = -wu * u
    jac[1, 0] = 0.0
    jac[1, 1] = -wu * comp[1]
    jac[1, 2] = 0.0
    jac[1, 3] = -wu * dg * dtpsi
    jac[1, 4] = -wu * tpsi
    return u, dgt_dtt, dgt_dag, dag_den, dag_des


@inner
def _opening_row(x, en_old, p, q, ws, we, r, jac):
    """Row 2: G_f^I (eps_n - eps_n_old) - <T_n>_w dgamma g_n [Pa m] times we [1/(Pa m)].

    eps_n' = <T_n> u_n^p' / G_f^I (Carol's pairing, PAPER_NOTES Sect. 4.2) with the work rule's
    <T_n>_w = theta <T_s,n> + (1 - theta) <T_n>, ws = (theta, <T_s,n>, .) (see _work_start).
    """
    tn, dg = x[1], x[4]
    tpsi, dtpsi = q[3], q[7]
    gf = p[P_GF1]
    th = ws[0]
    mac = th * ws[1] + (1.0 - th) * max(tn, 0.0)
    h = (1.0 - th) if tn > 0.0 else 0.0
    r[2] = we * (gf * (x[2] - en_old) - mac * dg * tpsi)
    jac[2, 0] = 0.0
    jac[2, 1] = -we * h * dg * tpsi
    jac[2, 2] = we * gf
    jac[2, 3] = -we * mac * dg * dtpsi
    jac[2, 4] = -we * mac * tpsi


@inner
def _slip_row(x, es_old, p, q, gt, ws, we, r, jac):
    """Row 3: G_f^II (eps_s - eps_s_old) - <|T_t| + T_n* tan phi>_w dgamma |g_t| [Pa m] times we.

    eps_s' = <|T_t| + T_n* tan phi> |u_t^p'| / G_f^II (Carol's pairing) with the work rule's mean
    theta m_s + (1 - theta) <.>, ws = (theta, ., m_s). gt = (g_t, dg_t/dT_t, dg_t/da_G,
    da_G/deps_n, da_G/deps_s) from the jump rows.
    """
    tt, tn, dg = x[0], x[1], x[4]
    tphi, dtphi = q[2], q[6]
    gf = p[P_GF2]
    sg = _sign(tt)
    ng, dng_dtt, dng_dag = sg * gt[0], sg * gt[1], sg * gt[2]
    tn_star = min(tn, 0.0)
    arg = abs(tt) + tn_star * tphi
    th = ws[0]
    m = th * ws[2] + (1.0 - th) * max(arg, 0.0)
    h = (1.0 - th) if arg > 0.0 else 0.0
    dm_dtt = h * sg
    dm_dtn = h * tphi if tn < 0.0 else 0.0
    dm_des = h * tn_star * dtphi
    r[3] = we * (gf * (x[3] - es_old) - m * dg * ng)
    jac[3, 0] = -we * dg * (dm_dtt * ng + m * dng_dtt)
    jac[3, 1] = -we * dg * dm_dtn * ng
    jac[3, 2] = -we * dg * m * dng_dag * gt[3]
    jac[3, 3] = we * (gf - dg * (dm_des * ng + m * dng_dag * gt[4]))
    jac[3, 4] = -we * m * ng


@inner
def _yield_row(x, q, s, r, jac):
    """Row 4: F(T, q) / s of eq. (18) and its gradient (safe at the corner T_t = a_F = 0)."""
    tt, tn = x[0], x[1]
    chi, c, tphi, _, dchi, dc, dtphi, _ = q
    a_f = c - chi * tphi
    r_f = math.sqrt(tt * tt + a_f * a_f)
    v = _ratio(a_f, r_f)
    daf_den = dc - tphi * dchi
    daf_des = daf_den - chi * dtphi
    r[4] = (r_f - c + tn * tphi) / s
    jac[4, 0] = _ratio(tt, r_f) / s
    jac[4, 1] = tphi / s
    jac[4, 2] = (v * daf_den - dc) / s
    jac[4, 3] = (v * daf_des - dc + tn * dtphi) / s
    jac[4, 4] = 0.0


@kernel
def _system(x, du, t_old, en_old, es_old, comp, wu, p, ws, r, jac):
    """Scaled residual r (5,) and Jacobian jac (5, 5) of the local problem at x (see module doc).

    Row weights make every row a relative error: jump rows by wu = 1/L_u [1/m], ISV rows (in
    energy form) by wu/s, the yield row by 1/s, s = c_p + chi_p [Pa]. ws: start-of-flow terms of the
    work rule (_work_start).
    """
    s = _scale(p)
    q = _isv(x[2], x[3], p)
    gt = _jump_rows(x, du, t_old, comp, wu, q, r, jac)
    _opening_row(x, en_old, p, q, ws, wu / s, r, jac)
    _slip_row(x, es_old, p, q, gt, ws, wu / s, r, jac)
    _yield_row(x, q, s, r, jac)


@kernel
def _jump_weight(comp, du, p):
    """Weight 1/L_u [1/m] of the jump rows, L_u = max(C) s + |du| (elastic plus applied jump)."""
    lu = max(comp[0], comp[1]) * _scale(p) + math.sqrt(du[0] * du[0] + du[1] * du[1])
    if not lu > 0.0:
        lu = _scale(p) / K_RP_SCALE
    return 1.0 / lu


# --------------------------------------------------------------------------------------------
# work rule: where plastic flow starts in the step
# --------------------------------------------------------------------------------------------


@kernel
def _work_start(t_s, du, comp, en_old, es_old, p, start, ws, dws):
    """Start-of-flow terms of the work rule: ws = (theta, <T_s,n>, <|T_s,t| + T_s,n* tan phi_old>) [-, Pa, Pa]
    and dws = their du-derivatives [Pa/m] (rows 1-2 of ws).

    theta = p[P_THETA] (0: backward Euler, nothing else is needed). start: START_GIVEN, T_s = t_s;
    START_CROSSING, T_s = t_s + a K^e du where F(T_s, q_old) = 0, a in [0, 1] (a = 0 if t_s is on
    the surface); F is convex along the path and positive at a = 1, so Newton from a = 1 decreases
    monotonically to the root. START_NONE: theta := 0.
    """
    for k in range(3):
        ws[k] = 0.0
    for i in range(2):
        for j in range(2):
            dws[i, j] = 0.0
    if p[P_THETA] == 0.0 or start == START_NONE:
        return
    ws[0] = p[P_THETA]
    chi, c, tphi, _ = strengths(en_old, es_old, p)
    tt, tn = t_s[0], t_s[1]
    dtt0 = dtt1 = dtn0 = dtn1 = 0.0  # dT_s/d(du)
    if start == START_CROSSING and yield_function(tt, tn, en_old, es_old, p) < -elastic_tolerance(p):
        kdt, kdn = du[0] / comp[0], du[1] / comp[1]
        a_f = c - chi * tphi
        a = 1.0
        slope = 0.0
        for _ in range(60):
            xt, xn = tt + a * kdt, tn + a * kdn
            r_f = math.sqrt(xt * xt + a_f * a_f)
            slope = _ratio(xt, r_f) * kdt + tphi * kdn
            if not slope > 0.0:
                break
            step = (r_f - c + xn * tphi) / slope
            a = min(max(a - step, 0.0), 1.0)
            if abs(step) <= 1.0e-15:
                break
        xt, xn = tt + a * kdt, tn + a * kdn
        if slope > 0.0:  # implicit function: F_T . K^e (du da + a d(du)) = 0
            r_f = math.sqrt(xt * xt + a_f * a_f)
            ft = _ratio(xt, r_f)
            da0 = -a * ft / comp[0] / slope
            da1 = -a * tphi / comp[1] / slope
            dtt0, dtt1 = kdt * da0 + a / comp[0], kdt * da1
            dtn0, dtn1 = kdn * da0, kdn * da1 + a / comp[1]
        tt, tn = xt, xn
    if tn > 0.0:
        ws[1] = tn
        dws[0, 0], dws[0, 1] = dtn0, dtn1
    arg = abs(tt) + min(tn, 0.0) * tphi
    if arg > 0.0:
        ws[2] = arg
        sg = _sign(tt)
        kn = tphi if tn < 0.0 else 0.0
        dws[1, 0] = sg * dtt0 + kn * dtn0
        dws[1, 1] = sg * dtt1 + kn * dtn1
