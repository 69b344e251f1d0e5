"""A registered traction law on 3D interfaces: the face the cohesive groups see (the TractionLaw
methods they call), over the 3D return of :mod:`rockfrac.laws.traction3d`.

Local frame (t1, t2, n), tension positive, tractions in Pa, jumps in m; the state layout is
``state_names_3d`` (T_t1, T_t2, T_n, jump_p_t1, jump_p_t2, jump_p_n, then the law's own slots). The
law's scalar quantities (yield function, records, dissipation) are those of its 2D form at |T_t|.
"""

from __future__ import annotations

import numpy as np

from rockfrac.laws.traction3d import (
    S_TN,
    S_TT1,
    S_TT2,
    check_3d,
    dgamma_slot_3d,
    ep_form_3d,
    mode_slot_3d,
    planar_states,
    rp_form_3d,
    state_names_3d,
)
from rockfrac.laws.traction_law import TractionLaw


class Law3D:
    """The 3D form of a 2D traction law (isotropic in the interface plane); ValueError if it has none."""

    dim = 3

    def __init__(self, law: TractionLaw):
        check_3d(law)
        self.planar = law
        self.name = law.name
        self.kn, self.kt = law.kn, law.kt
        self.p = law.p
        self.state_names = state_names_3d(type(law))
        self.mode_slot = mode_slot_3d(type(law))
        self.dgamma_slot = dgamma_slot_3d(type(law))
        self.record_names = law.record_names
        self.tensile_record = law.tensile_record

    @property
    def n_state(self) -> int:
        return len(self.state_names)

    @property
    def rigid(self) -> bool:
        return self.planar.rigid

    @property
    def scale(self) -> float:
        return self.planar.scale

    def initial_state(self, n: int) -> np.ndarray:
        return np.zeros((n, self.n_state))

    def ep_points(self, frame, weight, djump, s_old, d_old, s_new, d_new, fe, ke, status) -> None:
        """The EP form at every point: blocks (n, 6), (n, 6, 6)."""
        ep_form_3d(self.planar, frame, weight, djump, s_old, d_old, s_new, d_new, fe, ke, status)

    def rp_points(self, frame, weight, djump, lam, aug, eps, pinned, s_old, d_old, mode_prev, s_new, d_new, fe,
                  ke, status, switched) -> None:
        """The RP form at every point: blocks (n, 9), (n, 9, 9)."""
        rp_form_3d(self.planar, frame, weight, djump, lam, aug, eps, pinned, s_old, d_old, mode_prev, s_new, d_new,
                   fe, ke, status, switched)

    def records(self, state: np.ndarray) -> dict[str, np.ndarray]:
        return self.planar.records(planar_states(state))

    def yield_values(self, state: np.ndarray) -> np.ndarray:
        return self.planar.yield_values(planar_states(state))

    def separated(self, state: np.ndarray, fraction: float) -> np.ndarray:
        return self.planar.separated(planar_states(state), fraction)

    def dissipation(self, state: np.ndarray) -> np.ndarray:
        return self.planar.dissipation(planar_states(state))

    def softening_modulus(self) -> float:
        return self.planar.softening_modulus()

    def flow(self, state: np.ndarray) -> np.ndarray:
        """Local flow directions (n, 3) at the states' tractions: the 2D law's (g_t, g_n) with g_t
        along T_t (t1 where T_t = 0)."""
        g = self.planar.flow(planar_states(state))
        tt = np.hypot(state[:, S_TT1], state[:, S_TT2])
        safe = np.where(tt > 0.0, tt, 1.0)
        e1 = np.where(tt > 0.0, state[:, S_TT1] / safe, 1.0)
        e2 = np.where(tt > 0.0, state[:, S_TT2] / safe, 0.0)
        return np.stack([g[:, 0] * e1, g[:, 0] * e2, g[:, 1]], axis=1)

    def elastic_energy(self, state: np.ndarray, weight: np.ndarray) -> float:
        """sum w (|T_t|^2 / kt + T_n^2 / kn) / 2 [J]: the penalty's stored energy (0 for RP)."""
        if self.rigid:
            return 0.0
        assert self.kt is not None and self.kn is not None
        t2 = state[:, S_TT1] ** 2 + state[:, S_TT2] ** 2
        return float(0.5 * np.sum(weight * (t2 / self.kt + state[:, S_TN] ** 2 / self.kn)))
