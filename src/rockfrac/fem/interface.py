"""Zero-thickness interface kinematics with nodal integration: the blocks of a (minus, plus) node
pair from its local traction and tangent, and the multiplier rows of the rigid-plastic form.

Each point is a (minus, plus) node pair, dofs (minus x, minus y, plus x, plus y[, lambda x, lambda y])
(3D: minus xyz, plus xyz[, lambda xyz], local frame (t1, t2, n));
the jump is u(+) - u(-) in the global frame, rotated into the local (t, n) frame by R (rows t, n);
a local traction T gives the global T_g = R^T T, entering the weak form (5) as + int [[w]] . T ds.
Compiled helpers, inlined into the traction laws' point loops (one loop per law: a law's update is
inlined, which a function passed at run time could not be).
"""

from __future__ import annotations

from rockfrac.compiled import inner

CHUNK = 256  # points per prange chunk (one scratch per chunk)


@inner
def pair_blocks_local(r, w, t_t, t_n, d, fe, ke):
    """Force and stiffness of one node pair, dofs (minus x, minus y, plus x, plus y), from the local
    traction (t_t, t_n) and tangent d: global T_g = R^T t, D_g = R^T d R; on scalars, no temporaries."""
    tg0 = r[0, 0] * t_t + r[1, 0] * t_n
    tg1 = r[0, 1] * t_t + r[1, 1] * t_n
    fe[0] = -w * tg0
    fe[1] = -w * tg1
    fe[2] = w * tg0
    fe[3] = w * tg1
    for i in range(2):
        for j in range(2):
            s = 0.0
            for a in range(2):
                for b in range(2):
                    s += r[a, i] * d[a, b] * r[b, j]
            k = w * s
            ke[i, j] = k
            ke[i, 2 + j] = -k
            ke[2 + i, j] = -k
            ke[2 + i, 2 + j] = k


@inner
def multiplier_rows(r, w, t_t, t_n, lam, aug, fi, ki):
    """The rigid-plastic pair's multiplier rows and columns (paper eq. 32-33), after
    :func:`pair_blocks_local` wrote the displacement blocks of the traction T = (t_t, t_n) (local)
    computed at the augmented trial lambda + r h: rows w (T_g - lambda) with dT/dlambda = D / r,
    dT/d[[u]] = D, d(T - lambda)/dlambda = D / r - I. lam (2,): the global multipliers [Pa]."""
    for a in range(2):
        tg_a = r[0, a] * t_t + r[1, a] * t_n
        fi[4 + a] = w * (tg_a - lam[a])
        for b in range(2):
            kab = ki[a, b]  # w R^T D R, as pair_blocks_local wrote it
            ki[a, 4 + b] = -kab / aug
            ki[2 + a, 4 + b] = kab / aug
            ki[4 + a, b] = -kab
            ki[4 + a, 2 + b] = kab
            ki[4 + a, 4 + b] = kab / aug - (w if a == b else 0.0)


@inner
def junction_rows(w, eps, ki, dim):
    """The matrix term -eps w of a constrained junction pair's perturbed-Lagrangian multiplier rows (its
    residual term is added by rockfrac.elements.cse_groups.CohesiveRP, which keeps the reference
    tractions). dim: 2 or 3 (the multiplier rows follow the 2 dim displacement dofs)."""
    for a in range(dim):
        ki[2 * dim + a, 2 * dim + a] -= eps * w


@inner
def local_jump(r, dj):
    """(t, n) components of a global jump (2,)."""
    return r[0, 0] * dj[0] + r[0, 1] * dj[1], r[1, 0] * dj[0] + r[1, 1] * dj[1]


@inner
def local_jump_3d(r, v):
    """(t1, t2, n) components of a global vector (3,)."""
    return (r[0, 0] * v[0] + r[0, 1] * v[1] + r[0, 2] * v[2], r[1, 0] * v[0] + r[1, 1] * v[1] + r[1, 2] * v[2],
            r[2, 0] * v[0] + r[2, 1] * v[1] + r[2, 2] * v[2])


@inner
def pair_blocks_3d(r, w, s, d, fe, ke):
    """Force (6,) and stiffness (6, 6) of one node pair, dofs (minus xyz, plus xyz), from the local
    traction s[0:3] [Pa] and tangent d (3, 3): T_g = R^T T, K = R^T d R, times the weight w [m^2]."""
    for a in range(3):
        tg = r[0, a] * s[0] + r[1, a] * s[1] + r[2, a] * s[2]
        fe[a] = -w * tg
        fe[3 + a] = w * tg
    for i in range(3):
        for j in range(3):
            acc = 0.0
            for a in range(3):
                for b in range(3):
                    acc += r[a, i] * d[a, b] * r[b, j]
            k = w * acc
            ke[i, j] = k
            ke[i, 3 + j] = -k
            ke[3 + i, j] = -k
            ke[3 + i, 3 + j] = k


@inner
def multiplier_rows_3d(r, w, s, lam, aug, eps, junction, fi, ki):
    """The multiplier rows and columns of a rigid-plastic pair (dofs 6-8: lambda xyz, global [Pa]), after
    :func:`pair_blocks_3d`: :func:`multiplier_rows` and, where ``junction``, :func:`junction_rows` in 3D."""
    for a in range(3):
        tg = r[0, a] * s[0] + r[1, a] * s[1] + r[2, a] * s[2]
        fi[6 + a] = w * (tg - lam[a])
        for b in range(3):
            kab = ki[a, b]
            ki[a, 6 + b] = -kab / aug
            ki[3 + a, 6 + b] = kab / aug
            ki[6 + a, b] = -kab
            ki[6 + a, 3 + b] = kab
            ki[6 + a, 6 + b] = kab / aug - (w if a == b else 0.0)
    if junction:
        junction_rows(w, eps, ki, 3)
