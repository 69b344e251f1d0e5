"""Drucker-Prager bulk solids (Q4 plane strain or Hex8): state per Gauss point, consistent tangent."""

from __future__ import annotations

import numba as nb
import numpy as np

from rockfrac.elements.solid import Evaluation, SolidGeometry
from rockfrac.fem.kinematics import b_matrix
from rockfrac.fem.reference import ReferenceElement
from rockfrac.laws import drucker_prager as dp
from rockfrac.laws.drucker_prager_params import N_STATE, S_MODE, DruckerPrager


@nb.njit(cache=True, inline="always")
def integrate_point(b, w, sig6, c6, idx, fe, ke, cb):
    """fe += w B^T sigma, ke += w B^T C B on the element's Voigt components idx; cb is scratch (nv, nd)."""
    nv, nd = b.shape
    for i in range(nd):
        s = 0.0
        for k in range(nv):
            s += b[k, i] * sig6[idx[k]]
        fe[i] += w * s
    for k in range(nv):
        for j in range(nd):
            s = 0.0
            for l in range(nv):
                s += c6[idx[k], idx[l]] * b[l, j]
            cb[k, j] = w * s
    for i in range(nd):
        for j in range(nd):
            s = 0.0
            for k in range(nv):
                s += b[k, i] * cb[k, j]
            ke[i, j] += s


@nb.njit(cache=True, inline="always")
def point_strain(b, ue, idx, eps6):
    """Full Voigt strain eps6 (6,) = B u_e on the components idx, zero elsewhere (plane strain)."""
    nv, nd = b.shape
    eps6[:] = 0.0
    for k in range(nv):
        s = 0.0
        for j in range(nd):
            s += b[k, j] * ue[j]
        eps6[idx[k]] = s


@nb.njit(cache=True)
def dp_element(grads, wdet, ue, s_old, p, s_new, sigma, fe, ke):
    """One Drucker-Prager cell: return map at its Gauss points, fe (nd,) [N] and ke (nd, nd).

    grads (n_qp, n_nodes, dim), wdet (n_qp,), ue (nd,) [m]; s_old/s_new (n_qp, N_STATE);
    sigma (n_qp, 6) [Pa]. Returns 0, or the (negative) status of a failed return.
    """
    n_qp, n_nodes, dim = grads.shape
    nd = n_nodes * dim
    nv = 3 if dim == 2 else 6
    idx = np.array([0, 1, 3]) if dim == 2 else np.arange(6)
    b = np.empty((nv, nd))
    cb = np.empty((nv, nd))
    eps6 = np.empty(6)
    c6 = np.empty((6, 6))
    fe[:] = 0.0
    ke[:, :] = 0.0
    status = 0
    for q in range(n_qp):
        b_matrix(grads[q], b)
        point_strain(b, ue, idx, eps6)
        st = dp.return_map(eps6, s_old[q], p, sigma[q], c6, s_new[q])
        if st < 0:
            status = st
            continue
        integrate_point(b, wdet[q], sigma[q], c6, idx, fe, ke, cb)
    return status


@nb.njit(cache=True, parallel=True)
def dp_blocks(grads, wdet, ue, s_old, p, s_new, sigma, fe, ke, status):
    """Drucker-Prager solids: :func:`dp_element` over all cells (n_el leading axis on every array);
    status (n_el,) < 0 where a return failed."""
    for e in nb.prange(grads.shape[0]):
        status[e] = dp_element(grads[e], wdet[e], ue[e], s_old[e], p, s_new[e], sigma[e], fe[e], ke[e])


class DruckerPragerSolid(SolidGeometry):
    """Nonassociative Drucker-Prager bulk; trial and committed state kept apart."""

    constant = False
    n_extra = 0
    checkpoint_attrs = ("state", "sigma")

    def __init__(self, nodes: np.ndarray, cells: np.ndarray, ref: ReferenceElement, law: DruckerPrager):
        super().__init__(nodes, cells, ref)
        self.law = law
        self.p = law.as_array()
        shape = (cells.shape[0], ref.points.shape[0])
        self.state = np.zeros(shape + (N_STATE,))
        self.trial = np.zeros_like(self.state)
        self.sigma = np.zeros(shape + (6,))  # committed stresses
        self.trial_sigma = np.zeros_like(self.sigma)
        self.status = np.zeros(shape[0], dtype=np.int64)

    def begin_step(self) -> None:
        self.trial[:] = self.state

    def commit(self) -> None:
        self.state[:] = self.trial
        self.sigma[:] = self.trial_sigma

    def evaluate(self, u: np.ndarray, u_n: np.ndarray) -> Evaluation:
        n_el, nd = self.dofs.shape
        fe = np.empty((n_el, nd))
        ke = np.empty((n_el, nd, nd))
        dp_blocks(self.grads, self.wdet, np.ascontiguousarray(u[self.dofs]), self.state, self.p, self.trial,
                  self.trial_sigma, fe, ke, self.status)
        bad = np.flatnonzero(self.status < 0)
        msg = (f"Drucker-Prager return failed in cells {bad[:5].tolist()} (no admissible return)"
               if bad.size else "")
        return Evaluation(fe, ke, ok=not bad.size, message=msg)

    def stresses(self, u: np.ndarray | None = None) -> np.ndarray:
        """Committed Gauss-point stresses (n_el, n_qp, 6) [Pa]."""
        return self.sigma

    def plastic_fraction(self) -> float:
        """Share of Gauss points whose last committed update was plastic."""
        return float(np.mean(self.state[..., S_MODE] > 0.0))
