"""Compiled kernel of the nodal embedded crack (rockfrac.elements.ede_nodal): plane-strain cells
with the shifted Heaviside enrichment of their nodes.

Element vector of a cell: (u, q) = (u_0x, u_0y, ..., q_0x, q_0y, ...), u the nodal displacements,
q the enrichment of each node. In a cut cell the displacement is

    u(x) = sum_a N_a u_a + sum_a e_a (H(x) - H_a) N_a q_a,

H = 1 on the + side of the crack and 0 on the other, H_a = H(x_a), e_a = 1 where node a carries
this crack's enrichment: each side is integrated on its own (its quadrature points of
rockfrac.fem.cut_cell, each with its own Drucker-Prager state), and the jump across the crack is
[[u]](x) = sum_a e_a N_a(x) q_a, whose traction (rockfrac.laws.embedded_penalty) acts on the q's at
the crack's two points. An uncut cell is the Drucker-Prager cell of its u's. The q of a node that
carries no enrichment is held at zero elsewhere (rockfrac.elements.ede_enrichment).
"""

from __future__ import annotations

import numba as nb
import numpy as np

from rockfrac.compiled import inner
from rockfrac.elements.plastic_solid import dp_element_into, element_scratch, n_chunks
from rockfrac.laws import drucker_prager as dp
from rockfrac.laws.embedded_penalty import crack_return, crack_return_3d
from rockfrac.threads import parallel_kernel

ST_OK = 0
ST_DP_FAIL = -3
ST_CRACK_FAIL = -4


@inner
def _strain_rows(g, n_nodes, dim, b):
    """b (rows, dim n_nodes) = B of the shape gradients g (n_nodes, dim) at a point: plane strain rows
    xx, yy, xy; 3D rows xx, yy, zz, xy, yz, xz (engineering shears)."""
    b[:, :] = 0.0
    for a in range(n_nodes):
        c = dim * a
        if dim == 2:
            gx, gy = g[a, 0], g[a, 1]
            b[0, c] = gx
            b[1, c + 1] = gy
            b[2, c], b[2, c + 1] = gy, gx
        else:
            gx, gy, gz = g[a, 0], g[a, 1], g[a, 2]
            b[0, c] = gx
            b[1, c + 1] = gy
            b[2, c + 2] = gz
            b[3, c], b[3, c + 1] = gy, gx
            b[4, c + 1], b[4, c + 2] = gz, gy
            b[5, c], b[5, c + 2] = gz, gx


#: the Voigt rows (xx, yy, zz, xy, yz, xz) a side point's strain has: plane strain's, a 3D cell's
PLANE_ROWS = np.array([0, 1, 3])
SOLID_ROWS = np.arange(6)


@inner
def _side_points(ue, enr, cw, cside, cgrads, chnode, cstate, dp_p, k, mu, ce, cstate_new, csigma, fe, ke, rows,
                 dim):
    """fe, ke (zeroed here) of a cut cell's side points: each a Drucker-Prager point on [B, B_q] (the
    rows of its strain: PLANE_ROWS in 2D, SOLID_ROWS in 3D). Returns a status.

    On one side of the crack B_q = B diag(e_a (H - H_a)) is B scaled node by node, the same at every
    point of the side, so each side's sums of w B^T C B and w B^T sigma are made on the u's (a quarter
    of the products) and spread onto (u, q) once."""
    n_nodes = enr.shape[0]
    nr = rows.shape[0]
    nu = dim * n_nodes
    b = np.empty((nr, nu))
    cb = np.empty((nr, nu))
    v = np.empty(nu)
    eps6 = np.zeros(6)
    c6 = np.empty((6, 6))
    work = np.empty((5, 6))
    f_side = np.zeros((2, nu))
    k_side = np.zeros((2, nu, nu))
    status = ST_OK
    for p in range(cw.shape[0]):
        w = cw[p]
        if w == 0.0:
            continue
        for a in range(n_nodes):  # the displacement u + (H - H_a) q of each node at this side's points
            factor = enr[a] * (cside[p] - chnode[a])
            for i in range(dim):
                v[dim * a + i] = ue[dim * a + i] + factor * ue[nu + dim * a + i]
        _strain_rows(cgrads[p], n_nodes, dim, b)
        for i in range(nr):
            acc = 0.0
            for j in range(nu):
                acc += b[i, j] * v[j]
            eps6[rows[i]] = acc
        st = dp.return_map_into(eps6, cstate[p], dp_p, k, mu, ce, work, csigma[p], c6, cstate_new[p])
        if st < 0:
            status = ST_DP_FAIL
            continue
        s = 1 if cside[p] > 0.5 else 0
        for i in range(nr):
            for j in range(nu):
                acc = 0.0
                for m in range(nr):
                    acc += c6[rows[i], rows[m]] * b[m, j]
                cb[i, j] = acc
        for a in range(nu):
            fa = 0.0
            for i in range(nr):
                fa += b[i, a] * csigma[p, rows[i]]
            f_side[s, a] += w * fa
            for c in range(nu):
                acc = 0.0
                for i in range(nr):
                    acc += b[i, a] * cb[i, c]
                k_side[s, a, c] += w * acc
    fe[:] = 0.0
    ke[:, :] = 0.0
    scale = np.empty(nu)
    for s in range(2):
        for a in range(n_nodes):
            for i in range(dim):
                scale[dim * a + i] = enr[a] * (s - chnode[a])
        for a in range(nu):
            fe[a] += f_side[s, a]
            fe[nu + a] += scale[a] * f_side[s, a]
            for c in range(nu):
                kv = k_side[s, a, c]
                ke[a, c] += kv
                ke[a, nu + c] += kv * scale[c]
                ke[nu + a, c] += scale[a] * kv
                ke[nu + a, nu + c] += scale[a] * scale[c] * kv
    return status


@inner
def _crack_point(wk, enr, shape, tg, dg, q0, fe, ke):
    """Add a crack point's traction tg (dim,) [Pa] and tangent dg (dim, dim) [Pa/m], global frame, of
    weight wk [m] to the q rows (from q0) of the enriched nodes (shape values N_a (n_nodes,))."""
    dim = tg.shape[0]
    n_nodes = enr.shape[0]
    for a in range(n_nodes):
        sa = wk * enr[a] * shape[a]
        if sa == 0.0:
            continue
        for i in range(dim):
            fe[q0 + dim * a + i] += sa * tg[i]
        for b in range(n_nodes):
            sab = sa * enr[b] * shape[b]
            if sab == 0.0:
                continue
            for i in range(dim):
                for j in range(dim):
                    ke[q0 + dim * a + i, q0 + dim * b + j] += sab * dg[i, j]


@inner
def _cut_cell(ue, enr, cw, cside, cgrads, chnode, cstate, cshape, cwk, cframe, ccp, dp_p, k, mu, ce,
              law, kt, kn, cstate_new, csigma, ccp_new, fe, ke):
    """One cut cell (module doc): its sides' Drucker-Prager points and its crack points. Returns a status."""
    n_nodes = enr.shape[0]
    status = _side_points(ue, enr, cw, cside, cgrads, chnode, cstate, dp_p, k, mu, ce, cstate_new, csigma, fe, ke,
                          PLANE_ROWS, 2)
    tr = np.empty(2)
    dloc = np.empty((2, 2))
    dg = np.empty((2, 2))
    tg = np.empty(2)
    q0 = 2 * n_nodes
    for kk in range(cwk.shape[0]):
        jx, jy = 0.0, 0.0
        for a in range(n_nodes):
            s = enr[a] * cshape[kk, a]
            jx += s * ue[q0 + 2 * a]
            jy += s * ue[q0 + 2 * a + 1]
        tx, ty, nx, ny = cframe[0, 0], cframe[0, 1], cframe[1, 0], cframe[1, 1]
        st = crack_return(tx * jx + ty * jy, nx * jx + ny * jy, ccp[kk], law, kt, kn, ccp_new[kk], tr, dloc)
        if st < 0:
            status = ST_CRACK_FAIL
        tg[0] = tr[0] * tx + tr[1] * nx
        tg[1] = tr[0] * ty + tr[1] * ny
        for i in range(2):  # D_g = R^T D R, R rows (t, n)
            for j in range(2):
                dg[i, j] = (cframe[0, i] * (dloc[0, 0] * cframe[0, j] + dloc[0, 1] * cframe[1, j])
                            + cframe[1, i] * (dloc[1, 0] * cframe[0, j] + dloc[1, 1] * cframe[1, j]))
        _crack_point(cwk[kk], enr, cshape[kk], tg, dg, q0, fe, ke)
    return status


@parallel_kernel(cost=1.0e-6)  # s per item, one thread (an estimate: a Drucker-Prager cell's, dp_blocks')
def uncut_blocks(grads, wdet, ue, dp_old, dp_p, cut_slot, dp_new, sigma, fe, ke, status):
    """The uncut cells of a nodal embedded-crack group as Drucker-Prager cells (dp_blocks' arrays); a
    cut cell (cut_slot >= 0) gives zero blocks and holds its Gauss points' state (its sides are
    :func:`cut_blocks`')."""
    n = grads.shape[0]
    dp_k, dp_mu = dp.moduli(dp_p)
    dp_ce = dp.elastic_matrix(dp_p)
    m = n_chunks(n)
    for ch in nb.prange(m):
        scratch = element_scratch(grads.shape[2], grads.shape[3])
        for e in range(ch * n // m, (ch + 1) * n // m):
            if cut_slot[e] >= 0:
                fe[e, :] = 0.0
                ke[e, :, :] = 0.0
                for q in range(dp_old.shape[1]):
                    for s in range(dp_old.shape[2]):
                        dp_new[e, q, s] = dp_old[e, q, s]
                status[e] = ST_OK
                continue
            st = dp_element_into(grads[e], wdet[e], ue[e], dp_old[e], dp_p, dp_k, dp_mu, dp_ce, dp_new[e], sigma[e],
                                 fe[e], ke[e], scratch)
            status[e] = ST_DP_FAIL if st < 0 else ST_OK


@parallel_kernel(cost=2.0e-5)  # s per item, one thread (an estimate: 12 side points and 3 crack points a cell)
def cut_blocks(ue, enr, cw, cside, cgrads, chnode, cstate, cshape, cwk, cframe, ccp, dp_p, law, kt, kn, cstate_new,
               csigma, ccp_new, fe, ke, status):
    """The cut cells (module doc): element vectors fe (n_cut, 4 n_nodes) and blocks ke on their (u, q).

    ue (n_cut, 4 n_nodes); enr (n_cut, n_nodes) 0/1; the sides: cw (n_cut, m) weights [m^2] (0: unused),
    cside (n_cut, m) 1 on the + side, cgrads (n_cut, m, n_nodes, 2), cstate/cstate_new (n_cut, m,
    N_STATE), csigma (n_cut, m, 6); chnode (n_cut, n_nodes) H_a; the crack: cshape (n_cut, k, n_nodes)
    N_a at its points, cwk (n_cut, k) weights [m], cframe (n_cut, 2, 2) rows (t, n), ccp/ccp_new (n_cut,
    k, N_CP); dp_p the sides' Drucker-Prager parameters; law: Sect. 4.1 parameters; kt, kn [Pa/m].
    status (n_cut,): 0 or a failure."""
    n = ue.shape[0]
    dp_k, dp_mu = dp.moduli(dp_p)
    dp_ce = dp.elastic_matrix(dp_p)
    for c in nb.prange(n):
        status[c] = _cut_cell(ue[c], enr[c], cw[c], cside[c], cgrads[c], chnode[c], cstate[c], cshape[c], cwk[c],
                              cframe[c], ccp[c], dp_p, dp_k, dp_mu, dp_ce, law, kt, kn, cstate_new[c], csigma[c],
                              ccp_new[c], fe[c], ke[c])


# -- general 3D cells (tet4, hex8) --------------------------------------------------------------------

@inner
def _cut_cell_3d(ue, enr, cw, cside, cgrads, chnode, cstate, cshape, cwk, cframe, ccp, dp_p, k, mu, ce, law, kt,
                 kn, cstate_new, csigma, ccp_new, fe, ke):
    """One cut 3D cell: its sides' Drucker-Prager points and its crack points (the 3D law,
    rockfrac.laws.embedded_penalty.crack_return_3d, in the frame (t1, t2, n) of cframe's rows)."""
    n_nodes = enr.shape[0]
    status = _side_points(ue, enr, cw, cside, cgrads, chnode, cstate, dp_p, k, mu, ce, cstate_new, csigma, fe, ke,
                          SOLID_ROWS, 3)
    jl = np.empty(3)
    tr = np.empty(3)
    dloc = np.empty((3, 3))
    dg = np.empty((3, 3))
    tg = np.empty(3)
    q0 = 3 * n_nodes
    for kk in range(cwk.shape[0]):
        wk = cwk[kk]
        if wk == 0.0:
            continue
        jg = np.zeros(3)
        for a in range(n_nodes):
            sa = enr[a] * cshape[kk, a]
            for i in range(3):
                jg[i] += sa * ue[q0 + 3 * a + i]
        for r in range(3):
            jl[r] = cframe[r, 0] * jg[0] + cframe[r, 1] * jg[1] + cframe[r, 2] * jg[2]
        st = crack_return_3d(jl, ccp[kk], law, kt, kn, ccp_new[kk], tr, dloc)
        if st < 0:
            status = ST_CRACK_FAIL
        for i in range(3):
            tg[i] = cframe[0, i] * tr[0] + cframe[1, i] * tr[1] + cframe[2, i] * tr[2]
        for i in range(3):  # D_g = R^T D R, R's rows the frame
            for j in range(3):
                acc = 0.0
                for r in range(3):
                    for c in range(3):
                        acc += cframe[r, i] * dloc[r, c] * cframe[c, j]
                dg[i, j] = acc
        _crack_point(wk, enr, cshape[kk], tg, dg, q0, fe, ke)
    return status


@parallel_kernel(cost=2.0e-4)  # s per item, one thread (an estimate: up to 160 side points a hexahedron)
def cut_blocks_3d(ue, enr, cw, cside, cgrads, chnode, cstate, cshape, cwk, cframe, ccp, dp_p, law, kt, kn,
                  cstate_new, csigma, ccp_new, fe, ke, status):
    """:func:`cut_blocks` of general 3D cells: fe (n_cut, 6 n_nodes), ke on their (u, q); cframe
    (n_cut, 3, 3) rows (t1, t2, n), ccp (n_cut, k, N_C3); crack points with weight 0 are padding."""
    n = ue.shape[0]
    dp_k, dp_mu = dp.moduli(dp_p)
    dp_ce = dp.elastic_matrix(dp_p)
    for c in nb.prange(n):
        status[c] = _cut_cell_3d(ue[c], enr[c], cw[c], cside[c], cgrads[c], chnode[c], cstate[c], cshape[c], cwk[c],
                                 cframe[c], ccp[c], dp_p, dp_k, dp_mu, dp_ce, law, kt, kn, cstate_new[c], csigma[c],
                                 ccp_new[c], fe[c], ke[c])
