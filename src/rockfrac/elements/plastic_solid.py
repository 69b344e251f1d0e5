"""Drucker-Prager bulk solids (Q4 plane strain or Hex8): state per Gauss point, consistent tangent."""

from __future__ import annotations

import numba as nb
import numpy as np

from rockfrac.compiled import inner, kernel
from rockfrac.elements.base import Evaluation
from rockfrac.elements.solid import SolidGroup
from rockfrac.fem.kinematics import (
    add_btcb,
    add_bts,
    b_matrix,
    plane_add_btcb,
    plane_add_bts,
    plane_point_strain,
    point_strain,
)
from rockfrac.fem.loads import StressField
from rockfrac.fem.reference import ReferenceElement
from rockfrac.laws import drucker_prager as dp
from rockfrac.laws.drucker_prager_params import N_STATE, S_EPS_P, S_GAMMA, S_MODE, DruckerPrager
from rockfrac.laws.elastic import isotropic_compliance
from rockfrac.threads import parallel_kernel


@inner
def integrate_point(b, w, sig6, c6, idx, fe, ke, cb):
    """fe += w B^T sigma, ke += w B^T C B on the element's Voigt components idx; cb is scratch (nv, nd)."""
    add_bts(b, w, sig6, idx, fe)
    add_btcb(b, w, c6, idx, cb, ke)


@inner
def plane_integrate_point(g, w, sig6, c6, fe, ke, cb):
    """:func:`integrate_point` of a plane cell from its gradients g (n_nodes, 2), B's zeros skipped."""
    plane_add_bts(g, w, sig6, fe)
    plane_add_btcb(g, w, c6, np.int64(3), cb, ke)


@inner
def element_scratch(n_nodes, dim):
    """Work arrays of :func:`dp_element_into`: B, C B (nv, nd), strain (6,), tangent (6, 6), return-map
    scratch (5, 6), Voigt positions idx (nv,)."""
    nd = n_nodes * dim
    nv = 3 if dim == 2 else 6
    idx = np.empty(nv, dtype=np.int64)
    if dim == 2:
        idx[0], idx[1], idx[2] = 0, 1, 3
    else:
        for k in range(6):
            idx[k] = k
    return np.empty((nv, nd)), np.empty((nv, nd)), np.empty(6), np.empty((6, 6)), np.empty((5, 6)), idx


@inner
def dp_element(grads, wdet, ue, s_old, p, s_new, sigma, fe, ke):
    """One Drucker-Prager cell: return map at its Gauss points, fe (nd,) [N] and ke (nd, nd).

    grads (n_qp, n_nodes, dim), wdet (n_qp,), ue (nd,) [m]; s_old/s_new (n_qp, N_STATE);
    sigma (n_qp, 6) [Pa]. Returns 0, or the (negative) status of a failed return.
    Allocating form of :func:`dp_element_into` (the reference path of the tests).
    """
    k, mu = dp.moduli(p)
    return dp_element_into(grads, wdet, ue, s_old, p, k, mu, dp.elastic_matrix(p), s_new, sigma, fe, ke,
                           element_scratch(grads.shape[1], grads.shape[2]))


@inner
def dp_element_into(grads, wdet, ue, s_old, p, k, mu, ce, s_new, sigma, fe, ke, scratch):
    """:func:`dp_element` with (k, mu) = moduli(p), ce = elastic_matrix(p) and the work arrays of
    :func:`element_scratch` passed in: no allocation per cell, the same arithmetic."""
    b, cb, eps6, c6, work, idx = scratch
    fe[:] = 0.0
    ke[:, :] = 0.0
    status = 0
    plane = grads.shape[2] == 2
    for q in range(grads.shape[0]):
        if plane:
            plane_point_strain(grads[q], ue, eps6)
        else:
            b_matrix(grads[q], b)
            point_strain(b, ue, idx, eps6)
        st = dp.return_map_into(eps6, s_old[q], p, k, mu, ce, work, sigma[q], c6, s_new[q])
        if st < 0:
            status = st
            continue
        if plane:
            plane_integrate_point(grads[q], wdet[q], sigma[q], c6, fe, ke, cb)
        else:
            integrate_point(b, wdet[q], sigma[q], c6, idx, fe, ke, cb)
    return status


@inner
def n_chunks(n):
    """Number of prange chunks over n items: scratch is allocated once per chunk, and 256 chunks
    balance any thread count here (nb.get_num_threads() would stop the kernels being cached)."""
    return max(1, min(n, 256))


@parallel_kernel(cost=1.05e-6)  # s per item, one thread (benchmarks/thread_rule.py)
def dp_blocks(grads, wdet, ue, s_old, p, s_new, sigma, fe, ke, status):
    """Drucker-Prager solids: :func:`dp_element` over all cells (n_el leading axis on every array);
    status (n_el,) < 0 where a return failed."""
    n = grads.shape[0]
    k, mu = dp.moduli(p)
    ce = dp.elastic_matrix(p)
    m = n_chunks(n)
    for ch in nb.prange(m):
        scratch = element_scratch(grads.shape[2], grads.shape[3])
        for e in range(ch * n // m, (ch + 1) * n // m):
            status[e] = dp_element_into(grads[e], wdet[e], ue[e], s_old[e], p, k, mu, ce, s_new[e], sigma[e],
                                        fe[e], ke[e], scratch)


class DruckerPragerSolid(SolidGroup):
    """Nonassociative Drucker-Prager bulk; trial and committed state kept apart."""

    checkpoint_attrs: tuple[str, ...] = ("state", "sigma", "dissipated")

    def __init__(self, nodes: np.ndarray, cells: np.ndarray, ref: ReferenceElement, law: DruckerPrager, *,
                 region: str = "bulk", cell_ids: np.ndarray | None = None):
        super().__init__(nodes, cells, ref, region=region, cell_ids=cell_ids)
        self.law = law
        self.p = law.as_array()
        shape = (cells.shape[0], ref.points.shape[0])
        self.state = np.zeros(shape + (N_STATE,))
        self.trial = np.zeros_like(self.state)
        self.sigma = np.zeros(shape + (6,))  # committed stresses
        self.trial_sigma = np.zeros_like(self.sigma)
        self.status = np.zeros(shape[0], dtype=np.int64)
        self._buffers: tuple[np.ndarray, np.ndarray] | None = None
        self.E, self.nu = law.E, law.nu
        self.eigenstrain: np.ndarray | None = None  # -S sigma0: an in-situ stress held in eps^p (engineering)
        self.dissipated = 0.0  # sum of w sigma : d eps^p over the committed steps [J]

    def set_initial_stress(self, stress: StressField) -> None:
        """sigma = Ce (eps - eps^p) starts at sigma0: eps^p starts at the eigenstrain -S sigma0 (reported
        plastic strains exclude it)."""
        sigma0 = self.initial_stress_at_points(stress)
        self.eigenstrain = -sigma0 @ isotropic_compliance(self.E, self.nu).T
        for st in (self.state, self.trial):
            st[..., S_EPS_P:S_EPS_P + 6] = self.eigenstrain
        self.sigma[...] = sigma0
        self.trial_sigma[...] = sigma0

    def initial_violation(self) -> str:
        f = yield_values(self.sigma.reshape(-1, 6), self.state.reshape(-1, N_STATE), self.p)
        scale = max(self.law.kappa0, 1.0)
        bad = np.flatnonzero(f > 1e-9 * scale)
        if not bad.size:
            return ""
        cell = self.whole_ids[bad[0] // self.sigma.shape[1]]
        return (f"the in-situ stress is outside the Drucker-Prager yield surface of region {self.region!r} at "
                f"{bad.size} Gauss points (first in cell {cell}: F = {f[bad[0]]:.4g} Pa > 0)")

    def element_buffers(self) -> tuple[np.ndarray, np.ndarray]:
        """fe (n_el, nd), ke (n_el, nd, nd) for evaluate(): new arrays, or the group's own ones
        refilled at every call if reuse_buffers (saves allocating and page-faulting ~0.5 GB per call
        at 1e6 cells; the caller must be done with the last Evaluation)."""
        n_el, nd = self.dofs.shape
        if not self.reuse_buffers:
            return np.empty((n_el, nd)), np.empty((n_el, nd, nd))
        if self._buffers is None:
            self._buffers = (np.empty((n_el, nd)), np.empty((n_el, nd, nd)))
        return self._buffers

    def begin_step(self) -> None:
        self.trial[:] = self.state

    def commit(self) -> None:
        d_eps_p = self.trial[..., S_EPS_P:S_EPS_P + 6] - self.state[..., S_EPS_P:S_EPS_P + 6]
        self.dissipated += float(0.5 * np.einsum("eqi,eqi,eq->", self.sigma + self.trial_sigma, d_eps_p, self.wdet))
        self.state[:] = self.trial
        self.sigma[:] = self.trial_sigma

    def dissipated_energy(self) -> float:
        return self.dissipated

    def evaluate(self, u: np.ndarray, u_n: np.ndarray) -> Evaluation:
        fe, ke = self.element_buffers()
        dp_blocks(self.grads, self.wdet,
                  np.ascontiguousarray(u[self.dofs]), self.state, self.p, self.trial, self.trial_sigma,
                  fe, ke, self.status)
        bad = np.flatnonzero(self.status < 0)
        msg = (f"Drucker-Prager return failed in cells {bad[:5].tolist()} (no admissible return)"
               if bad.size else "")
        return Evaluation(fe, ke, ok=not bad.size, message=msg)

    def stresses(self, u: np.ndarray | None = None) -> np.ndarray:
        """Committed Gauss-point stresses (n_el, n_qp, 6) [Pa]."""
        return self.sigma

    def cell_fields(self, u: np.ndarray) -> dict[str, np.ndarray]:
        out = super().cell_fields(u)
        eps_p = self.state[..., S_EPS_P:S_EPS_P + 6]
        out["plastic_strain"] = (eps_p if self.eigenstrain is None else eps_p - self.eigenstrain).mean(axis=1)
        out["gamma"] = self.state[..., S_GAMMA].mean(axis=1)
        return out

    def plastic_fraction(self) -> float:
        """Share of Gauss points whose last committed update was plastic."""
        return float(np.mean(self.state[..., S_MODE] > 0.0))


@kernel
def yield_values(sigma, state, p):
    """F at many points (n, 6) with their states (n, N_STATE) [Pa] (set-up checks)."""
    out = np.empty(sigma.shape[0])
    for i in range(sigma.shape[0]):
        out[i] = dp.yield_value(sigma[i], state[i, S_GAMMA], p)
    return out
