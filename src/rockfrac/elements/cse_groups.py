"""Cohesive-surface element groups (EP and RP) as the Newton solver sees them, over any traction law
(a :class:`rockfrac.laws.traction_law.TractionLaw` plug-in: its point loops, state and records).

A group evaluates all its points at once (compiled kernels, no Python loop over points),
keeps its committed and trial state apart and commits only on request. In 2D (local frame (t, n))
or 3D (local frame (t1, t2, n), the law a :class:`rockfrac.laws.law3d.Law3D`): the state starts
with the dim local tractions, then the dim plastic jumps.
"""

from __future__ import annotations

import numpy as np

from rockfrac.elements.base import ElementGroup, Evaluation, Measure
from rockfrac.elements.interface_points import InterfacePoints
from rockfrac.fem.loads import StressField
from rockfrac.laws.implex import implex_points
from rockfrac.laws.law3d import Law3D
from rockfrac.laws.traction_law import MODE_PLASTIC, TractionLaw
from rockfrac.laws.viscous import duvaut_lions_points, duvaut_lions_rp_points


class _CohesiveGroup(ElementGroup):
    """State handling shared by the EP and RP cohesive surfaces."""

    kind = "cohesive"
    rigid = False  # RP: constrained points have no elastic jump
    per_facet = False  # one point per edge or face (rockfrac.elements.cse_facets), not per node pair
    checkpoint_attrs: tuple[str, ...] = ("state", "tangent", "dissipated")

    MODES = {"": 0.0, "load": 1.0, "path": 2.0}  # control modes of a step, as stored in a checkpoint

    def __init__(self, points: InterfacePoints, law: TractionLaw | Law3D, *, name: str = "cohesive",
                 viscosity: float = 0.0):
        if not viscosity >= 0.0:
            raise ValueError(f"viscosity must be >= 0 (got {viscosity!r})")
        self.name = name
        self.points = points
        self.law = law
        self.viscosity = float(viscosity)
        self.viscous_dissipated = 0.0  # sum of w <T - T_bar> . d[[u^p]] over the committed steps [J] (trapezoidal)
        self._t_bar = np.zeros((points.n, points.dim))  # viscous: the law's own tractions of the last evaluation
        self.overstress = np.zeros((points.n, points.dim))  # viscous: committed T - T_bar [Pa]
        self._step = np.zeros(2)  # (control mode, size) of the step being solved
        self.mode = law.mode_slot
        n = points.n
        d = self.dim = points.dim
        self._t, self._up = slice(0, d), slice(d, 2 * d)  # the state's tractions and plastic jumps
        self.state = law.initial_state(n)  # committed
        self.trial = law.initial_state(n)
        self.tangent = np.zeros((n, d, d))  # committed local tangent dT/d[[u]]
        self.trial_tangent = np.zeros((n, d, d))
        self.status = np.zeros(n, dtype=np.int64)
        self.dissipated = 0.0  # sum of w T . d[[u^p]] over the committed steps [J]
        self.initial_traction = np.zeros((n, d))  # global in-situ tractions [Pa]
        self.jump_dofs = points.dofs  # (n, 2 d): each point's minus, then plus displacement dofs
        self.dofs = self.jump_dofs

    def jumps(self, u: np.ndarray) -> np.ndarray:
        """Global-frame jumps u(+) - u(-) at the points, (n_pts, dim) [m]."""
        d = self.dim
        return u[self.jump_dofs[:, d:]] - u[self.jump_dofs[:, :d]]

    def renumber(self, numbering) -> None:
        self.jump_dofs = numbering.local(self.jump_dofs)
        self.dofs = numbering.local(self.dofs)

    def begin_step(self) -> None:
        self.trial[:] = self.state
        self.trial_tangent[:] = self.tangent

    def set_step(self, mode: str, size: float) -> None:
        self._step[:] = (self.MODES[mode], size)

    def blend(self) -> float:
        """Viscous regularisation: a = r / (1 + r), r = dt / eta, dt the pseudo-time of the step (its
        load-factor increment; a step of another control, which the case refuses, has none)."""
        mode, size = self._step
        dt = size if mode == self.MODES["load"] else 0.0
        return dt / (self.viscosity + dt) if dt > 0.0 else 0.0

    def viscous_energy(self) -> float | None:
        return self.viscous_dissipated if self.viscosity > 0.0 else None

    def _committed_for_return(self) -> np.ndarray:
        """The committed state the law returns from: with viscosity a copy with every point's mode
        reset (an overstressed point returns even at a zero jump increment; the laws' shortcut for a
        committed plastic point would keep its overstress)."""
        if self.viscosity == 0.0:
            return self.state
        committed = self.state.copy()
        committed[:, self.mode] = 0.0
        return committed

    def commit(self) -> None:
        d_up = self.trial[:, self._up] - self.state[:, self._up]
        if self.viscosity > 0.0:
            over = self.trial[:, self._t] - self._t_bar
            self.viscous_dissipated += float(np.einsum("pi,pi,p->", 0.5 * (over + self.overstress), d_up,
                                                       self.points.weight))
            self.overstress[:] = over
        mean = 0.5 * (self.trial[:, self._t] + self.state[:, self._t])
        self.dissipated += float(np.einsum("pi,pi,p->", mean, d_up, self.points.weight))
        self.state[:] = self.trial
        self.tangent[:] = self.trial_tangent

    def dissipated_energy(self) -> float:
        return self.dissipated

    def separated(self, fraction: float) -> tuple[np.ndarray, float]:
        """The committed points that have lost their tensile strength, down to ``fraction`` of the
        virgin one (:meth:`TractionLaw.separated`), where the surface no longer holds its sides
        together: their (minus, plus) nodes (k, 2), and their tributary size, the crack's length [m]
        in 2D or area [m^2] in 3D."""
        hit = self.law.separated(self.state, fraction)
        return (np.stack([self.points.minus[hit], self.points.plus[hit]], axis=1),
                float(self.points.weight[hit].sum()))

    def holding(self, fraction: float) -> np.ndarray:
        """The (minus, plus) pairs (k, 2) this group holds that another MPI rank's points of the same
        pair might call separated: none, a pair's points are all on one rank (corner points: some)."""
        return np.zeros((0, 2), dtype=np.int64)

    def surface_energy(self) -> float:
        """sum w x the law's own dissipation per unit area [J] (an account independent of the time
        integration of ``dissipated``)."""
        return float(np.sum(self.points.weight * self.law.dissipation(self.state)))

    def set_initial_stress(self, stress: StressField) -> None:
        """The points start with the tractions the in-situ stress puts on the crack (consistent with
        the bulk on both sides), in the local frame of the state; nothing has yielded."""
        self.initial_traction = self.points.consistent_tractions(stress)
        local = self.points.local(self.initial_traction)
        for st in (self.state, self.trial):
            st[:, self._t] = local

    def initial_violation(self) -> str:
        f = self.law.yield_values(self.state)
        bad = np.flatnonzero(f > 1e-9 * self.law.scale)
        if not bad.size:
            return ""
        x = self.points.x[bad[0]]
        return (f"the in-situ stress puts {bad.size} points of {self.name} outside the traction law's yield "
                f"surface (first at ({', '.join(f'{v:.6g}' for v in x)}): F = {f[bad[0]]:.4g} Pa > 0)")

    def any_plastic(self) -> bool:
        """True if a point of the committed state is plastic."""
        return bool(np.any(self.state[:, self.mode] == MODE_PLASTIC))

    def flow_directions(self) -> np.ndarray:
        """Unit global-frame directions (n_pts, dim) of dG/dT at the committed tractions.

        Where each point slides or opens next under continued loading; the normal n where dG/dT
        vanishes (no shear traction and no dilatancy).
        """
        g = self.law.flow(self.state)
        norm = np.linalg.norm(g, axis=1)
        g = np.where(norm[:, None] > 0.0, g / np.where(norm > 0.0, norm, 1.0)[:, None], np.eye(self.dim)[-1])
        return np.einsum("pji,pj->pi", self.points.frame, g)  # R^T g

    def path_measure(self, n_dofs: int) -> Measure:
        return self.jump_measure(n_dofs)

    def path_active(self) -> bool:
        return self.any_plastic()

    def path_weight(self) -> int:
        return self.points.n

    def measure_mass(self) -> float:
        return float(self.points.weight.sum())

    BISECTIONS = 60  # halvings of the step fraction when locating an activation (2^-60: round-off)

    ON_SURFACE = 1e-9  # a committed point with F >= -ON_SURFACE x the law's strength scale has reached its surface

    def activation_pending(self) -> bool:
        """No point has yielded, nor reached its yield surface (a located activation is not located again)."""
        if self.dissipated != 0.0 or self.any_plastic():
            return False
        return not bool(np.any(self.law.yield_values(self.state) >= -self.ON_SURFACE * self.law.scale))

    def yielded(self) -> bool:
        return bool(np.any(self.trial[:, self.mode] == MODE_PLASTIC))

    def traction_increment(self, u: np.ndarray, du: np.ndarray) -> np.ndarray:
        """Local tractions' increment (n_pts, dim) [Pa] along du from the committed state while no
        point yields: the committed tangent on the jump increment (EP)."""
        dj = self.points.local(self.jumps(u + du) - self.jumps(u))
        return np.einsum("pij,pj->pi", self.tangent, dj)

    def activation(self, u: np.ndarray, du: np.ndarray) -> float | None:
        if not self.activation_pending():
            return None
        t0 = self.state[:, self._t].copy()
        dt = self.traction_increment(u, du)
        trial = self.state.copy()
        f0 = self.law.yield_values(trial)
        trial[:, self._t] = t0 + dt
        f1 = self.law.yield_values(trial)
        live = np.flatnonzero((f0 < -self.ON_SURFACE * self.law.scale) & (f1 > 0.0))
        if not live.size:
            return None
        at, t0, dt = trial[live], t0[live], dt[live]
        lo, hi = np.zeros(live.size), np.ones(live.size)  # F(lo) <= 0 < F(hi)
        for _ in range(self.BISECTIONS):
            mid = 0.5 * (lo + hi)
            at[:, self._t] = t0 + mid[:, None] * dt
            out = self.law.yield_values(at) > 0.0
            hi = np.where(out, mid, hi)
            lo = np.where(out, lo, mid)
        return float(lo.min())

    def point_records(self, u: np.ndarray) -> dict[str, np.ndarray]:
        """:meth:`records` with the plastic jump's norm, the state named and the set."""
        rec = self.records(u)
        rec["jump_p_norm"] = np.linalg.norm(self.state[:, self._up], axis=1)
        rec["state"] = np.where(rec["mode"] == MODE_PLASTIC, "plastic", "constrained" if self.rigid else "elastic")
        rec["set"] = np.full(rec["x"].shape[0], self.name)
        return rec

    def record_order(self) -> np.ndarray | None:
        return self.points.index

    def jump_measure(self, n_dofs: int) -> Measure:
        """Path-following measure for the next step: g(u) = sum(w m . [[u]]) / sum(w) [m], and dg/du.

        m are the flow directions of the committed state, frozen for the step, so g is linear in u
        and a positive increment means forward plastic flow (never the mirrored, unloading branch).
        """
        pts = self.points
        m = self.flow_directions() * (pts.weight / pts.weight.sum())[:, None]
        grad = np.zeros(n_dofs)
        d = self.dim
        np.add.at(grad, self.jump_dofs[:, d:], m)
        np.add.at(grad, self.jump_dofs[:, :d], -m)

        def measure(u: np.ndarray) -> tuple[float, np.ndarray]:
            return float(np.sum(m * self.jumps(u))), grad

        return measure

    def records(self, u: np.ndarray) -> dict[str, np.ndarray]:
        """Committed per-point quantities in the local frame (for points.csv): position, jump,
        traction, plastic jump, the law's own records, mode."""
        s = self.state
        jump = self.points.local(self.jumps(u))
        if self.dim == 3:
            return self._records_3d(s, jump)
        out = {
            "cell": self.points.cell,
            "x": self.points.x[:, 0],
            "y": self.points.x[:, 1],
            "angle": np.arctan2(self.points.frame[:, 0, 1], self.points.frame[:, 0, 0]),
            "jump_t": jump[:, 0],
            "jump_n": jump[:, 1],
            "T_t": s[:, 0],
            "T_n": s[:, 1],
            "jump_p_t": s[:, 2],
            "jump_p_n": s[:, 3],
        }
        out.update(self.law.records(s))
        out["mode"] = s[:, self.mode]
        return out

    def _records_3d(self, s: np.ndarray, jump: np.ndarray) -> dict[str, np.ndarray]:
        """:meth:`records` of 3D points: position, the normal, and the (t1, t2, n) components."""
        x, n = self.points.x, self.points.frame[:, 2]
        out = {"cell": self.points.cell, "x": x[:, 0], "y": x[:, 1], "z": x[:, 2],
               "n_x": n[:, 0], "n_y": n[:, 1], "n_z": n[:, 2]}
        for k, c in enumerate(("t1", "t2", "n")):
            out[f"jump_{c}"] = jump[:, k]
        for k, name in enumerate(("T_t1", "T_t2", "T_n", "jump_p_t1", "jump_p_t2", "jump_p_n")):
            out[name] = s[:, k]
        out.update(self.law.records(s))
        out["mode"] = s[:, self.mode]
        return out


class CohesiveEP(_CohesiveGroup):
    """Elasto-plastic CSE, K^e = diag(kt, kn) as penalty (paper Sect. 6.1).

    integration = "implicit": the law's return map at the end of the step (backward Euler, the
    paper's); "implex": the same update for the state, but equilibrium with the explicit traction
    of :mod:`rockfrac.laws.implex` (one Newton iteration per step, first order in the step size).
    viscosity eta > 0 [pseudo-time, one load-controlled stage = 1]: the implicit update regularised
    by :mod:`rockfrac.laws.viscous` (Duvaut-Lions), its extra dissipation kept in
    ``viscous_dissipated``.
    """

    n_extra = 0

    def __init__(self, points: InterfacePoints, law: TractionLaw | Law3D, *, name: str = "cohesive",
                 integration: str = "implicit", viscosity: float = 0.0):
        if law.rigid:
            raise ValueError("an EP cohesive surface needs finite kn and kt")
        if integration not in ("implicit", "implex"):
            raise ValueError(f"integration must be 'implicit' or 'implex', got {integration!r}")
        if not viscosity >= 0.0 or (viscosity > 0.0 and integration != "implicit"):
            raise ValueError(f"viscosity must be >= 0 and regularises the implicit update only (got {viscosity!r} "
                             f"with integration {integration!r})")
        if points.dim == 3 and integration != "implicit":
            raise ValueError("IMPL-EX integration is 2D only; 3D surfaces are integrated implicitly")
        super().__init__(points, law, name=name, viscosity=viscosity)
        d = self.dim
        self.up_prev = np.zeros((points.n, d))  # IMPL-EX: committed plastic jumps one step earlier [m]
        self.step_prev = np.zeros(2)  # IMPL-EX: (control mode, size) of the last committed step
        self._t_ex = np.zeros((points.n, d))  # IMPL-EX: the explicit tractions of the last evaluation
        self.implex = np.array(1.0 if integration == "implex" else 0.0)  # 1: IMPL-EX (as checkpointed)

    checkpoint_attrs = _CohesiveGroup.checkpoint_attrs + ("up_prev", "step_prev", "implex", "viscous_dissipated",
                                                       "overstress")

    @property
    def integration(self) -> str:
        return "implex" if self.implex == 1.0 else "implicit"

    def implex_error(self) -> float | None:
        """IMPL-EX: the largest |T_ex - T| over the points at the converged iterate, relative to the
        law's strength (T the implicit traction of the state): the scheme's error in the step, which
        the stepping keeps below [solver] implex_tol (Oliver et al. 2008). None when implicit."""
        if self.integration != "implex" or self.points.n == 0:
            return None
        gap = np.linalg.norm(self._t_ex - self.trial[:, self._t], axis=1)
        return float(gap.max()) / self.law.scale

    def switch_to_implex(self) -> bool:
        if self.implex == 1.0 or self.viscosity > 0.0 or self.dim == 3:
            return False
        self.implex = np.array(1.0)
        return True

    def step_ratio(self) -> float:
        """dt_{n+1} / dt_n for the extrapolation: the sizes of this step and the last committed one
        when both are controlled alike; else 0, no extrapolation (a load increment against a path
        increment has no ratio: extrapolating the last plastic jump whole put the first path step
        after a switch 140 strengths off, whatever its size). The step is then explicit on the
        committed state, its error of first order in its size, which the step control sees."""
        (mode, size), (mode_prev, size_prev) = self._step, self.step_prev
        return size / size_prev if mode == mode_prev and mode > 0.0 and size_prev > 0.0 else 0.0

    def commit(self) -> None:
        self.up_prev[:] = self.state[:, self._up]  # kept in both modes: a switch has its history
        self.step_prev[:] = self._step
        super().commit()

    def elastic_energy(self, u: np.ndarray) -> float:
        """sum w (T_t^2 / kt + T_n^2 / kn) / 2 [J]: the penalty's elastic energy."""
        return self.law.elastic_energy(self.state, self.points.weight)

    def evaluate(self, u: np.ndarray, u_n: np.ndarray) -> Evaluation:
        pts = self.points
        djump = self.jumps(u) - self.jumps(u_n)
        n, nd = pts.n, 2 * self.dim
        fe = np.empty((n, nd))
        ke = np.empty((n, nd, nd))
        mode_prev = self.trial[:, self.mode].copy()  # the previous iterate's (a change is a switch)
        committed = self._committed_for_return()
        self.law.ep_points(pts.frame, pts.weight, djump,
                           committed, self.tangent, self.trial, self.trial_tangent, fe, ke, self.status)
        if self.integration == "implex":  # the state as above; equilibrium with the explicit traction
            assert self.law.kt is not None and self.law.kn is not None
            implex_points(pts.frame, pts.weight, djump, self.state, self.up_prev, self.step_ratio(),
                          float(self.law.kt), float(self.law.kn), self._t_ex, fe, ke)
        elif self.viscosity > 0.0:  # the law's return, relaxed towards the elastic trial (Duvaut-Lions)
            assert self.law.kt is not None and self.law.kn is not None
            duvaut_lions_points(pts.frame, pts.weight, djump, self.state, self.trial, self.trial_tangent,
                                self.blend(), float(self.law.kt), float(self.law.kn), np.int64(self.law.dgamma_slot),
                                np.int64(self.mode), self._t_bar, fe, ke)
        bad = np.flatnonzero(self.status < 0)
        msg = f"EP traction law failed at interface points {bad[:5].tolist()}" if bad.size else ""
        switched = int(np.count_nonzero(self.trial[:, self.mode] != mode_prev))
        return Evaluation(fe, ke, ok=not bad.size, n_switched=switched, message=msg)


class CohesiveRP(_CohesiveGroup):
    """Rigid-plastic CSE with augmented Lagrange multipliers (paper Sect. 6.2, eq. 32-34).

    Owns two multiplier dofs (global-frame traction) per point, numbered from ``offset``; see
    :func:`rockfrac.elements.cse.rp_points` for the augmented return and why its converged
    state solves eq. (34).

    Junctions: around a node split into k >= 3 copies the pairs' jumps sum to zero, so their
    multipliers are statically indeterminate (forces may circulate round the node: a singular
    system). At such pairs, while constrained, the multiplier row gets a perturbed-Lagrangian term
    JUNCTION_EPS w (lambda - lambda_ref): the circulating part takes the value nearest lambda_ref, at a
    constraint violation of JUNCTION_EPS dlambda / r, ~1e-13 m. lambda_ref is the committed traction
    (for a uniform stress the circulation is then exactly w sigma . n, the physical traction: the
    normals round a node sum to zero), until an iterate of the step finds the pair plastic: from then
    on it is that iterate's traction (on the surface; with viscosity, the relaxed one). Until
    2026-11-29 it stayed the committed traction: a pair that the circulation had put on its surface
    was pulled back inside when held shut, and then pushed out again; the grains' junction pairs
    flipped so at every iteration (benchmarks/README.md, "A grain-matrix specimen in compression").

    viscosity eta > 0 [pseudo-time, one load-controlled stage = 1]: the augmented return regularised
    by :mod:`rockfrac.laws.viscous` (Duvaut-Lions with K = r I: the plastic jump's rate is the
    overstress over eta r), its extra dissipation kept in ``viscous_dissipated``.
    """

    JUNCTION_EPS = 1e-8
    PIN_AFTER_FLIPS = 2  # a point that switched this often in a step is held constrained (active set)
    PIN_TOLERANCE = 1e-9  # a held point is let go where F > PIN_TOLERANCE x the law's strength scale
    rigid = True
    rings = True  # its points' multipliers may close rings round a split node (per-cell multipliers do not)

    def __init__(self, points: InterfacePoints, law: TractionLaw | Law3D, augmentation: float,
                 junction: np.ndarray | None = None, *, name: str = "cohesive", viscosity: float = 0.0):
        super().__init__(points, law, name=name, viscosity=viscosity)
        if self.viscosity > 0.0:  # an inviscid run's checkpoint keeps its layout
            self.checkpoint_attrs = type(self).checkpoint_attrs + ("viscous_dissipated", "overstress")
        self.aug = float(augmentation)
        self.eps = np.where(junction, self.JUNCTION_EPS, 0.0) if junction is not None else np.zeros(points.n)
        self._at_junction = self.eps > 0.0
        self._flips = np.zeros(points.n, dtype=np.int64)  # switches in the current step
        self._pinned = np.zeros(points.n, dtype=bool)
        self._released = np.zeros(points.n, dtype=bool)  # pinned once and let go in this step
        self._lam_ref = np.zeros((points.n, self.dim))  # junction pairs' reference multipliers (global) [Pa]
        self.n_extra = self.dim * points.n
        self.offset = -1
        self.lam_dofs = np.zeros((0, self.dim), dtype=np.int64)  # each point's multiplier dofs (n_pts, dim)
        self.total_points = points.n  # the whole set's, on every MPI rank (its points are points.index of them)

    def begin_step(self) -> None:
        super().begin_step()
        self._lam_ref = self.points.from_local(self.state[:, self._t])
        self._flips[:] = 0
        self._pinned[:] = False
        self._released[:] = False

    def set_offset(self, offset: int) -> None:
        """Number the multiplier dofs from ``offset`` on: point k's are offset + dim index_k + (0..dim-1),
        index_k its place in the whole set (its own place on one process; on an MPI rank, the whole
        set's numbering, so every rank agrees on it)."""
        self.offset = offset
        self.lam_dofs = offset + self.dim * np.asarray(self.points.index)[:, None] + np.arange(self.dim)
        self.dofs = np.hstack([self.jump_dofs, self.lam_dofs])

    def renumber(self, numbering) -> None:
        super().renumber(numbering)
        self.lam_dofs = numbering.local(self.lam_dofs)

    def multiplier_blocks(self) -> np.ndarray:
        """The points whose multipliers (dim each) this group holds, by their index in the whole set."""
        return np.asarray(self.points.index)

    def extra_span(self) -> int:
        return self.dim * self.total_points

    def initial_unknowns(self, u0: np.ndarray) -> None:
        """The multipliers start at the in-situ tractions (global frame)."""
        u0[self.lam_dofs] = self.initial_traction

    def redundant_extras(self, dirichlet: np.ndarray) -> np.ndarray:
        """Multiplier dofs whose constraint the Dirichlet conditions already impose: both nodes of the
        pair held in that (global) component, e.g. the copies of a split node on a supported edge.
        Their rows would be empty (a singular system); they are prescribed to zero instead, and the
        supports take that traction component."""
        d = self.dim
        held = np.isin(self.jump_dofs, dirichlet)
        out = []
        for a in range(d):
            both = held[:, a] & held[:, d + a]
            out.append(self.lam_dofs[both, a])
        return np.concatenate(out).astype(np.int64)

    def multipliers(self, u: np.ndarray) -> np.ndarray:
        """Global-frame multipliers (n_pts, dim) [Pa]."""
        return u[self.lam_dofs]

    def traction_increment(self, u: np.ndarray, du: np.ndarray) -> np.ndarray:
        """Local tractions' increment (n_pts, dim) [Pa] along du while every point is constrained: the
        multipliers' (the jumps stay zero)."""
        return self.points.local(self.multipliers(u + du) - self.multipliers(u))

    def _junction_residual(self, lam: np.ndarray, fe: np.ndarray) -> None:
        """Add the perturbed-Lagrangian term -JUNCTION_EPS w (lambda - lambda_ref) to the multiplier rows
        of the constrained junction pairs (global frame; its matrix term is the kernels'), then take the
        tractions of this iterate's plastic junction pairs as their lambda_ref."""
        if not self._at_junction.any():
            return
        d = self.dim
        plastic = self.trial[:, self.mode] == MODE_PLASTIC
        held = self._at_junction & ~plastic
        fe[held, 2 * d:] -= (self.eps * self.points.weight)[held, None] * (lam[held] - self._lam_ref[held])
        moved = self._at_junction & plastic
        self._lam_ref[moved] = np.einsum("pji,pj->pi", self.points.frame[moved], self.trial[moved][:, self._t])

    def evaluate(self, u: np.ndarray, u_n: np.ndarray) -> Evaluation:
        pts = self.points
        djump = self.jumps(u) - self.jumps(u_n)
        n, nd = pts.n, 3 * self.dim
        fe = np.empty((n, nd))
        ke = np.empty((n, nd, nd))
        switched = np.zeros(n, dtype=np.int64)
        mode_prev = self.trial[:, self.mode].copy()
        lam = self.multipliers(u)
        committed = self._committed_for_return()
        self.law.rp_points(pts.frame, pts.weight, djump, lam, self.aug, self.eps, self._pinned, committed,
                           self.tangent, mode_prev, self.trial, self.trial_tangent, fe, ke, self.status, switched)
        if self.viscosity > 0.0:  # the augmented return, relaxed towards the trial lambda + r h (Duvaut-Lions)
            duvaut_lions_rp_points(pts.frame, pts.weight, djump, lam, self.aug, self.eps, committed, self.trial,
                                   self.trial_tangent, self.blend(), np.int64(self.law.dgamma_slot),
                                   np.int64(self.mode), self._t_bar, fe, ke)
        self._junction_residual(lam, fe)
        # active-set pinning: a point chattering between constrained and plastic (on its yield
        # surface, dgamma ~ 0) is held constrained for the rest of the step; it is consistent there
        # only if its traction is inside the surface, else it is released (once per step)
        self._flips += switched
        self._pinned |= (self._flips >= self.PIN_AFTER_FLIPS) & ~self._released
        local = 0.0
        if self._pinned.any():
            with np.errstate(over="ignore", invalid="ignore"):  # a diverging iterate's tractions: the step fails on them
                f = self.law.yield_values(self.trial[self._pinned])
            scale = self.law.scale
            outside = f > self.PIN_TOLERANCE * scale
            if outside.any():
                idx = np.flatnonzero(self._pinned)[outside]
                self._pinned[idx] = False
                self._released[idx] = True
                local = float(f[outside].max() / scale)
        bad = np.flatnonzero(self.status < 0)
        msg = (f"RP return map failed at interface points {bad[:5].tolist()} (if the law softens faster "
               f"than the augmentation r = {self.aug:.3g} Pa/m, raise [cohesive] augmentation)") if bad.size else ""
        return Evaluation(fe, ke, ok=not bad.size, n_switched=int(switched.sum()), message=msg,
                          local_residual=max(local, 1.0) if local > 0 else 0.0)
