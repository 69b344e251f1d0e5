"""Acoustic tensor A(n) of a Voigt modulus, det A, its gradients and det A / det A^e (Numba)."""

from __future__ import annotations

import numpy as np

from rockfrac.compiled import inner, kernel

# --------------------------------------------------------------------------------------------
# acoustic tensor, its determinant and gradients (Numba)
# --------------------------------------------------------------------------------------------


@inner
def _cn_row(c, a, n0, n1, n2):
    """Row a of C N(n) (3 values): N(n)'s three nonzeros per column, in the order of the full sum."""
    return (c[a, 0] * n0 + c[a, 3] * n1 + c[a, 5] * n2,
            c[a, 1] * n1 + c[a, 3] * n0 + c[a, 4] * n2,
            c[a, 2] * n2 + c[a, 4] * n1 + c[a, 5] * n0)


@kernel
def _acoustic(c, n, out):
    """out (3, 3) = N(n)^T c N(n): A_ik = n_j C_ijkl n_l for c (6, 6) Voigt.

    N(n) (6, 3), strain-like sym(a x n) = N(n) a, has rows (n0,0,0), (0,n1,0), (0,0,n2), (n1,n0,0),
    (0,n2,n1), (n2,0,n0); its zeros are skipped (no work arrays) and the nonzero products summed in
    the order of the full products, so the values are those of the dense form.
    """
    a = _acoustic9(c, n[0], n[1], n[2])
    out[0, 0], out[0, 1], out[0, 2] = a[0], a[1], a[2]
    out[1, 0], out[1, 1], out[1, 2] = a[3], a[4], a[5]
    out[2, 0], out[2, 1], out[2, 2] = a[6], a[7], a[8]


@kernel
def _acoustic_dense(c, n, out):
    """The dense form of :func:`_acoustic` (reference of the tests)."""
    nm = np.zeros((6, 3))  # strain-like sym(a x n) = nm @ a
    nm[0, 0] = n[0]
    nm[1, 1] = n[1]
    nm[2, 2] = n[2]
    nm[3, 0], nm[3, 1] = n[1], n[0]
    nm[4, 1], nm[4, 2] = n[2], n[1]
    nm[5, 0], nm[5, 2] = n[2], n[0]
    cn = np.zeros((6, 3))
    for a in range(6):
        for k in range(3):
            acc = 0.0
            for b in range(6):
                acc += c[a, b] * nm[b, k]
            cn[a, k] = acc
    for i in range(3):
        for k in range(3):
            acc = 0.0
            for a in range(6):
                acc += nm[a, i] * cn[a, k]
            out[i, k] = acc


@kernel
def acoustic_tensor(c, n):
    """Acoustic tensor A(n) (3, 3) [Pa] of the Voigt modulus c (6, 6) for the normal n (3,)."""
    out = np.empty((3, 3))
    _acoustic(c, n, out)
    return out


@inner
def _cofactor(a, cof):
    """cof (3, 3) = d det(a) / d a_ik; returns det(a)."""
    cof[0, 0] = a[1, 1] * a[2, 2] - a[1, 2] * a[2, 1]
    cof[0, 1] = a[1, 2] * a[2, 0] - a[1, 0] * a[2, 2]
    cof[0, 2] = a[1, 0] * a[2, 1] - a[1, 1] * a[2, 0]
    cof[1, 0] = a[0, 2] * a[2, 1] - a[0, 1] * a[2, 2]
    cof[1, 1] = a[0, 0] * a[2, 2] - a[0, 2] * a[2, 0]
    cof[1, 2] = a[0, 1] * a[2, 0] - a[0, 0] * a[2, 1]
    cof[2, 0] = a[0, 1] * a[1, 2] - a[0, 2] * a[1, 1]
    cof[2, 1] = a[0, 2] * a[1, 0] - a[0, 0] * a[1, 2]
    cof[2, 2] = a[0, 0] * a[1, 1] - a[0, 1] * a[1, 0]
    return a[0, 0] * cof[0, 0] + a[0, 1] * cof[0, 1] + a[0, 2] * cof[0, 2]


@inner
def _acoustic9(c, n0, n1, n2):
    """A(n) of :func:`_acoustic` as 9 values, row by row (no arrays)."""
    r0 = _cn_row(c, np.int64(0), n0, n1, n2)
    r1 = _cn_row(c, np.int64(1), n0, n1, n2)
    r2 = _cn_row(c, np.int64(2), n0, n1, n2)
    r3 = _cn_row(c, np.int64(3), n0, n1, n2)
    r4 = _cn_row(c, np.int64(4), n0, n1, n2)
    r5 = _cn_row(c, np.int64(5), n0, n1, n2)
    return (n0 * r0[0] + n1 * r3[0] + n2 * r5[0], n0 * r0[1] + n1 * r3[1] + n2 * r5[1],
            n0 * r0[2] + n1 * r3[2] + n2 * r5[2],
            n1 * r1[0] + n0 * r3[0] + n2 * r4[0], n1 * r1[1] + n0 * r3[1] + n2 * r4[1],
            n1 * r1[2] + n0 * r3[2] + n2 * r4[2],
            n2 * r2[0] + n1 * r4[0] + n0 * r5[0], n2 * r2[1] + n1 * r4[1] + n0 * r5[1],
            n2 * r2[2] + n1 * r4[2] + n0 * r5[2])


@inner
def _cofactor9(a):
    """(det, cofactors row by row) of a 3x3 given as 9 values; :func:`_cofactor`'s formulas."""
    a00, a01, a02, a10, a11, a12, a20, a21, a22 = a
    c00 = a11 * a22 - a12 * a21
    c01 = a12 * a20 - a10 * a22
    c02 = a10 * a21 - a11 * a20
    c10 = a02 * a21 - a01 * a22
    c11 = a00 * a22 - a02 * a20
    c12 = a01 * a20 - a00 * a21
    c20 = a01 * a12 - a02 * a11
    c21 = a02 * a10 - a00 * a12
    c22 = a00 * a11 - a01 * a10
    return a00 * c00 + a01 * c01 + a02 * c02, (c00, c01, c02, c10, c11, c12, c20, c21, c22)


@inner
def _det_grad3(c, n0, n1, n2):
    """(det A(n), d det A / d n) of :func:`_det_grad` as scalars (no arrays, the same arithmetic)."""
    det, cof = _cofactor9(_acoustic9(c, n0, n1, n2))
    out0 = 0.0
    out1 = 0.0
    out2 = 0.0
    for m in range(3):
        ep = _acoustic9(c, n0 + (1.0 if m == 0 else 0.0), n1 + (1.0 if m == 1 else 0.0),
                        n2 + (1.0 if m == 2 else 0.0))
        em = _acoustic9(c, n0 - (1.0 if m == 0 else 0.0), n1 - (1.0 if m == 1 else 0.0),
                        n2 - (1.0 if m == 2 else 0.0))
        acc = 0.0
        for ik in range(9):
            acc += cof[ik] * 0.5 * (ep[ik] - em[ik])
        if m == 0:
            out0 = acc
        elif m == 1:
            out1 = acc
        else:
            out2 = acc
    g = (out0, out1, out2)
    return det, g


@inner
def _det_grad(c, n, grad):
    """det A(n) and grad (3,) = d det A / d n (n not normalized: A is quadratic in n).

    dA_ik/dn_m = C_imkl n_l + n_j C_ijkm, i.e. N(e_m)^T c N(n) + N(n)^T c N(e_m); computed from
    A(n + e_m) - A(n - e_m) = 2 dA/dn_m (exact: A is quadratic in n).
    """
    det, g = _det_grad3(c, n[0], n[1], n[2])
    for m in range(3):
        grad[m] = g[m]
    return det


@inner
def _ratio_grad3(c, ce, n0, n1, n2):
    """(r, dr/dn as 3 values) of :func:`_ratio_grad`, no arrays."""
    d1, g1 = _det_grad3(c, n0, n1, n2)
    d2, g2 = _det_grad3(ce, n0, n1, n2)
    return d1 / d2, ((g1[0] * d2 - d1 * g2[0]) / (d2 * d2), (g1[1] * d2 - d1 * g2[1]) / (d2 * d2),
                     (g1[2] * d2 - d1 * g2[2]) / (d2 * d2))


@inner
def _ratio_grad(c, ce, n, grad):
    """r = det A(n) / det A^e(n) and grad (3,) = dr/dn."""
    r, g = _ratio_grad3(c, ce, n[0], n[1], n[2])
    for m in range(3):
        grad[m] = g[m]
    return r


@inner
def _ratio3(c, ce, n0, n1, n2):
    """det A(n) / det A^e(n) for n = (n0, n1, n2), no arrays."""
    d1, _ = _cofactor9(_acoustic9(c, n0, n1, n2))
    d2, _ = _cofactor9(_acoustic9(ce, n0, n1, n2))
    return d1 / d2


@kernel
def _ratio(c, ce, n):
    """det A(n) / det A^e(n)."""
    return _ratio3(c, ce, n[0], n[1], n[2])


@kernel
def det_ratios(c, ce, normals):
    """det A(n) / det A^e(n) at each row of normals (k, 3); returns (k,)."""
    out = np.empty(normals.shape[0])
    for i in range(normals.shape[0]):
        out[i] = _ratio(c, ce, normals[i])
    return out


@inner
def lowest_ratio(c, normals, det_e, a, cof):
    """The lowest det A(n) / det A^e(n) over the given normals (k, 3), with det A^e (k,) computed
    once for them, and the index of its normal: (ratio, k). a, cof: (3, 3) scratch."""
    best, k_best = np.inf, 0
    for k in range(normals.shape[0]):
        _acoustic(c, normals[k], a)
        r = _cofactor(a, cof) / det_e[k]
        if r < best:
            best, k_best = r, k
    return best, k_best


@inner
def elastic_dets(ce, normals):
    """det A^e(n) (k,) of the elastic acoustic tensor at each of the normals (k, 3)."""
    out = np.empty(normals.shape[0])
    a = np.empty((3, 3))
    cof = np.empty((3, 3))
    for k in range(normals.shape[0]):
        _acoustic(ce, normals[k], a)
        out[k] = _cofactor(a, cof)
    return out
