"""Element groups: what the Newton solver sees (dofs, residual and tangent blocks, state).

A group evaluates all its elements at once (compiled kernels, no Python loop over elements),
keeps its committed and trial state apart and commits only on request.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rockfrac.elements import cse
from rockfrac.elements.interface_points import InterfacePoints
from rockfrac.fem import quad4
from rockfrac.fem.dofs import node_dofs
from rockfrac.laws import cohesive as _law
from rockfrac.laws.cohesive_params import N_STATE, S_EPSN, S_EPSS, S_MODE, CohesiveLaw


@dataclass
class Evaluation:
    """Element vectors fe (n_el, nd), blocks ke (n_el, nd, nd); ok False if a local solve failed."""

    fe: np.ndarray
    ke: np.ndarray
    ok: bool = True
    n_switched: int = 0
    message: str = ""


class ElasticQ4:
    """Linear elastic plane-strain Q4 bulk; its stiffness is constant and assembled once."""

    constant = True
    n_extra = 0

    def __init__(self, nodes: np.ndarray, quads: np.ndarray, E: float, nu: float):
        self.x = np.ascontiguousarray(nodes[quads])
        self.quads = quads
        self.E, self.nu = E, nu
        self.d = quad4.plane_strain_elasticity(E, nu)
        self.dofs = node_dofs(quads)
        self.ke = quad4.elastic_stiffness(self.x, self.d, quad4.DN_REF)
        if not np.all(np.isfinite(self.ke)):
            raise ValueError("inverted or degenerate quadrilateral in the bulk mesh")

    def stresses(self, u: np.ndarray) -> np.ndarray:
        """Gauss-point stresses (n_el, 4, 4) as (xx, yy, zz, xy) [Pa], plane strain."""
        eps = quad4.gauss_strains(self.x, u[self.dofs], quad4.DN_REF)
        s = eps @ self.d.T
        szz = self.nu * (s[..., 0] + s[..., 1])
        return np.stack([s[..., 0], s[..., 1], szz, s[..., 2]], axis=-1)

    # constant groups have nothing to commit
    def begin_step(self) -> None: ...

    def commit(self) -> None: ...


class _CohesiveGroup:
    """State handling shared by the EP and RP cohesive surfaces."""

    constant = False

    def __init__(self, points: InterfacePoints, law: CohesiveLaw):
        self.points = points
        self.law = law
        self.p = law.as_array()
        n = points.n
        self.state = np.zeros((n, N_STATE))  # committed
        self.trial = np.zeros((n, N_STATE))
        self.tangent = np.zeros((n, 2, 2))  # committed local tangent dT/d[[u]]
        self.trial_tangent = np.zeros((n, 2, 2))
        self.status = np.zeros(n, dtype=np.int64)

    def begin_step(self) -> None:
        self.trial[:] = self.state
        self.trial_tangent[:] = self.tangent

    def commit(self) -> None:
        self.state[:] = self.trial
        self.tangent[:] = self.trial_tangent

    def records(self, u: np.ndarray) -> dict[str, np.ndarray]:
        """Committed per-point quantities in the local frame (for points.csv)."""
        s = self.state
        chi, c, tphi, tpsi = strengths_array(s[:, S_EPSN], s[:, S_EPSS], self.p)
        jump = self.points.local(self.points.jumps(u))
        return {
            "cell": self.points.cell,
            "x": self.points.x[:, 0],
            "y": self.points.x[:, 1],
            "jump_t": jump[:, 0],
            "jump_n": jump[:, 1],
            "T_t": s[:, 0],
            "T_n": s[:, 1],
            "jump_p_t": s[:, 2],
            "jump_p_n": s[:, 3],
            "eps_n_p": s[:, S_EPSN],
            "eps_s_p": s[:, S_EPSS],
            "chi": chi,
            "c": c,
            "tan_phi": tphi,
            "tan_psi": tpsi,
            "mode": s[:, S_MODE],
        }


def strengths_array(eps_n: np.ndarray, eps_s: np.ndarray, p: np.ndarray) -> tuple[np.ndarray, ...]:
    """chi, c, tan(phi), tan(psi) at many points (vectorized over the compiled scalar law)."""
    out = np.array([_law.strengths(a, b, p) for a, b in zip(eps_n, eps_s)]).reshape(-1, 4)
    return out[:, 0], out[:, 1], out[:, 2], out[:, 3]


class CohesiveEP(_CohesiveGroup):
    """Elasto-plastic CSE, K^e = diag(kt, kn) as penalty (paper Sect. 6.1)."""

    n_extra = 0

    def __init__(self, points: InterfacePoints, law: CohesiveLaw):
        if law.rigid:
            raise ValueError("an EP cohesive surface needs finite kn and kt")
        super().__init__(points, law)
        self.dofs = points.dofs

    def evaluate(self, u: np.ndarray, u_n: np.ndarray) -> Evaluation:
        pts = self.points
        djump = pts.jumps(u) - pts.jumps(u_n)
        n = pts.n
        fe = np.empty((n, 4))
        ke = np.empty((n, 4, 4))
        cse.ep_points(pts.frame, pts.weight, djump, self.state, self.p, self.trial,
                      self.trial_tangent, fe, ke, self.status)
        bad = np.flatnonzero(self.status < 0)
        msg = f"EP traction law failed at interface points {bad[:5].tolist()}" if bad.size else ""
        return Evaluation(fe, ke, ok=not bad.size, message=msg)


class CohesiveRP(_CohesiveGroup):
    """Rigid-plastic CSE with augmented Lagrange multipliers (paper Sect. 6.2, eq. 32-34).

    Owns two multiplier dofs (global-frame traction) per point, numbered from ``offset``.
    """

    def __init__(self, points: InterfacePoints, law: CohesiveLaw, augmentation: float):
        super().__init__(points, law)
        self.aug = float(augmentation)
        self.n_extra = 2 * points.n
        self.offset = -1

    def set_offset(self, offset: int) -> None:
        """Number the multiplier dofs from ``offset`` on."""
        self.offset = offset
        lam = offset + np.arange(2 * self.points.n).reshape(-1, 2)
        self.dofs = np.hstack([self.points.dofs, lam])

    def multipliers(self, u: np.ndarray) -> np.ndarray:
        """Global-frame multipliers (n_pts, 2) [Pa]."""
        return u[self.offset : self.offset + self.n_extra].reshape(-1, 2)

    def evaluate(self, u: np.ndarray, u_n: np.ndarray) -> Evaluation:
        pts = self.points
        djump = pts.jumps(u) - pts.jumps(u_n)
        n = pts.n
        fe = np.empty((n, 6))
        ke = np.empty((n, 6, 6))
        switched = np.zeros(n, dtype=np.int64)
        prev = self.trial.copy()
        cse.rp_points(pts.frame, pts.weight, djump, self.multipliers(u), self.aug, self.state,
                      prev, self.tangent, self.p, self.trial, self.trial_tangent, fe, ke,
                      self.status, switched)
        bad = np.flatnonzero(self.status < 0)
        msg = f"RP local problem (34) failed at interface points {bad[:5].tolist()}" if bad.size else ""
        return Evaluation(fe, ke, ok=not bad.size, n_switched=int(switched.sum()), message=msg)
