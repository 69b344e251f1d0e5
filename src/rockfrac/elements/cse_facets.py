"""Cohesive surfaces with one point per interface cell (``[cohesive] points = "edges"`` in 2D, ``"faces"``
in 3D): the point's jump is its edge's or face's mean jump, and moments, elastic up to the tension
cap, resist the cell's relative rotations.

rockfrac's nodal points (paper Sect. 6.2) put a point on each (minus, plus) node pair. With surfaces
on every edge a node is split into one copy per cell and its pairs close a ring whose jumps sum to
zero, so rigid-plastic pairs there flow only together: a crack that bends at a node, or meets unyielded
pairs, cannot slide (benchmarks/README.md, "Points per edge"). A facet point constrains the mean jump
(dim conditions a cell instead of dim per node pair), which leaves no ring. Its rotations are held
elastically, with no unknown added:

- bending, about axes in the cell (2D: the one rotation):

      E_b = k/2 g^T S g,   g_a = n . (u_pa - u_ma),   S = int N N^T dA - w w^T / A,   w = int N dA

  on the normal jumps g of the cell's node pairs, the penalty's energy of their zero-mean part
  (k = kn, or the augmentation r for RP; in 2D E_b = k L (g_1 - g_0)^2 / 24 [J/m]);
- torsion, about the normal (3D): E_t = k_t/2 (b . J)^2 / I, b_a = int N_a n x (x - c) dA, I = int
  |x - c|^2 dA (c the centroid), the penalty's energy of the jump's projection on a rigid rotation
  about the normal (k_t = kt, or r). Without it, tetrahedra round an edge turn about their faces'
  normals as a mechanism.

So the yielded cells do not turn about their centroids as hinges, and a plane's stretch is left to
the bulk. The bending is elastic-plastic: its traction at each corner v, T_n + k e_v (e the zero-mean
part of g - g_p, g_p the bending's plastic part), stays below the point's tension cap,

      k max_v e_v <= C,   C = max(0, chi - T_n)   (chi: the law's tensile strength, T_n: its normal traction)

returned radially (e scaled to the cap; in 2D |Delta| <= C, Delta = k (g_1 - g_0 - rho_p) / 2 the end
tractions' deviation, the moment L Delta / 6 conjugate to g_1 - g_0). So an edge that has opened at
one end rocks open like a pair of nodal points, and an edge in compression keeps its moment up to
the pressure. The tangent is consistent: dC/d(jump, multiplier) by forward differences of the
law's own update at the capped points only. The plastic bending dissipates q . dg_p (kept in
``dissipated``, reported apart in history.csv's ``D_bending``); the torsion stays elastic. The law, its return, the viscosity and the RP multipliers are the nodal points' own: each
point's rows (minus, plus[, multiplier]) are mapped onto the cell's nodes, each node taking its share
w_a / A.
"""

from __future__ import annotations

from dataclasses import replace
from typing import NamedTuple

import numpy as np

from rockfrac.elements.base import Evaluation, Measure
from rockfrac.elements.cse_groups import CohesiveEP, CohesiveRP
from rockfrac.elements.interface_points import InterfacePoints, local_frames_3d
from rockfrac.fem.loads import face_rule
from rockfrac.laws.law3d import Law3D
from rockfrac.laws.traction_law import TractionLaw
from rockfrac.laws.viscous import duvaut_lions_points, duvaut_lions_rp_points


class FacetShape(NamedTuple):
    """What a facet point needs of its cell's shape: each node's share of the mean jump w_a / A (n, m),
    the bending matrix S (n, m, m) [m or m^2], and in 3D the torsion's b (n, m, 3) [m^3] and I (n,)
    [m^4] (2D: None)."""

    share: np.ndarray
    bending: np.ndarray
    torsion: np.ndarray | None
    polar: np.ndarray | None


def facet_points(nodes: np.ndarray, cells: np.ndarray,
                 index: np.ndarray | None = None) -> tuple[InterfacePoints, FacetShape]:
    """One point per interface cell (m_0 .. m_{m-1}, p_0 .. p_{m-1}): a 2D edge (m = 2) or a 3D triangle
    or quadrilateral face (m = 3, 4), at its centroid, weight its length [m] or area [m^2]; frame rows
    (t, n) with t from m0 to m1 in 2D, (t1, t2, n) about the face's mean normal in 3D (the nodal points'
    conventions); the points' (minus, plus) are the cells' first pair; and the cells' shapes. ``index``:
    each cell's place among all of the set's (an MPI rank's share; default: these are all), which is
    also the points' ``cell``."""
    cells = np.asarray(cells, dtype=np.int64)
    k, m = cells.shape[0], cells.shape[1] // 2
    xm = nodes[cells[:, :m]]
    torsion = polar = None
    if nodes.shape[1] == 2:
        size = np.linalg.norm(xm[:, 1] - xm[:, 0], axis=1)
        t = (xm[:, 1] - xm[:, 0]) / size[:, None]
        frame = np.stack([t, np.stack([-t[:, 1], t[:, 0]], axis=1)], axis=1)
        share = np.full((k, 2), 0.5)
        bending = (size / 12.0)[:, None, None] * np.array([[1.0, -1.0], [-1.0, 1.0]])
        centre = 0.5 * (xm[:, 0] + xm[:, 1])
    else:
        shape, xq, nda = face_rule(xm)  # exact for N_a N_b on flat triangles and bilinear faces
        da = np.linalg.norm(nda, axis=2)
        w = np.einsum("qa,kq->ka", shape, da)
        size = w.sum(axis=1)
        share = w / size[:, None]
        bending = np.einsum("qa,qb,kq->kab", shape, shape, da) - w[:, :, None] * share[:, None, :]
        normal = nda.sum(axis=1)
        normal /= np.linalg.norm(normal, axis=1)[:, None]
        frame = local_frames_3d(normal)
        centre = np.einsum("ka,kai->ki", share, xm)
        arm = np.cross(normal[:, None, :], xq - centre[:, None, :])  # n x (x - c) at the Gauss points
        torsion = np.einsum("qa,kqi,kq->kai", shape, arm, da)
        polar = np.einsum("kqi,kqi,kq->k", arm, arm, da)
    idx = np.arange(k)
    place = idx if index is None else np.asarray(index, dtype=np.int64)
    pts = InterfacePoints(minus=cells[:, 0].copy(), plus=cells[:, m].copy(), weight=size, frame=frame,
                          x=centre, cell=place.copy(), segments=cells,
                          segment_points=np.repeat(idx[:, None], m, axis=1), segment_x=xm, index=place.copy())
    return pts, FacetShape(share, bending, torsion, polar)


class _OnFacets:
    """What a facet point changes of a nodal point: its jump, its rows on the cell's nodes (m_0 ..
    m_{m-1}, p_0 .. p_{m-1}), the moments on the cell's rotations, and the nodes a separated point parts."""

    per_facet = True
    dim: int
    points: InterfacePoints
    jump_dofs: np.ndarray
    dofs: np.ndarray
    rigid: bool  # RP (the multipliers' rows follow the cell's displacement rows)
    dissipated: float  # the group's work account [J/m, J]
    rotation_stiffness: float  # k of the bending [Pa/m]
    moment_cap: bool = True  # the bending's corner tractions capped by the tension cap (False: elastic)
    FD_STEP = 1e-7  # the differences' step for dC/d(jump, multiplier): this fraction of the law's strength
    CAP_TOLERANCE = 1e-9  # a bending is capped where it exceeds C by this fraction of the law's strength (not by
    # round-off: a separated point has C = 0, and an elastic bending of 1e-20 Pa there is no yield)
    torsion_stiffness: float  # k_t of the torsion [Pa/m] (3D)
    _cells: np.ndarray  # (n, 2 m): each point's cell
    _shape: FacetShape
    _source: np.ndarray  # the point's row (minus, plus[, multiplier]) of each of the cell's rows
    _share: np.ndarray  # (n, rows): and the share it takes (w_a / A for a node, all of a multiplier's)
    _normal_rows: np.ndarray  # (n, m, 2 m dim): g = normal_rows . u over the cell's nodes
    _mean: np.ndarray  # (n, dim, 2 m dim): the mean jump's global components over the cell's displacement dofs
    _torsion_rows: np.ndarray | None  # (n, 2 m dim): b . J = torsion_rows . u (3D)

    def _on_facets(self, cells: np.ndarray, shape: FacetShape, multipliers: bool) -> None:
        d, n = self.dim, cells.shape[0]
        m = cells.shape[1] // 2
        ar = np.arange(d)
        self._cells, self._shape = cells, shape
        self.jump_dofs = (d * cells[:, :, None] + ar).reshape(n, 2 * m * d)
        self.dofs = self.jump_dofs
        self._source = np.concatenate([ar] * m + [d + ar] * m + ([2 * d + ar] if multipliers else []))
        nodes = np.repeat(shape.share, d, axis=1)
        self._share = np.concatenate([nodes, nodes] + ([np.ones((n, d))] if multipliers else []), axis=1)
        normal = self.points.frame[:, -1]
        rows = np.zeros((n, m, 2, m, d))
        for a in range(m):
            rows[:, a, 0, a] = -normal
            rows[:, a, 1, a] = normal
        self._normal_rows = rows.reshape(n, m, 2 * m * d)
        mean = np.zeros((n, d, 2, m, d))
        for i in range(d):
            mean[:, i, 0, :, i] = -shape.share
            mean[:, i, 1, :, i] = shape.share
        self._mean = mean.reshape(n, d, 2 * m * d)
        self._torsion_rows = None
        self.bend_plastic = np.zeros((n, m))  # committed plastic normal jumps of the bending g_p [m]
        self.bend_force = np.zeros((n, m))  # committed bending forces q = k S (g - g_p) [N/m per m in 2D, N in 3D]
        self.moment_dissipated = 0.0  # sum of q . d g_p over the committed steps [J/m in 2D, J in 3D]
        self._bend_trial = np.zeros((n, m))
        self._force_trial = np.zeros((n, m))
        self.capped = np.zeros(n, dtype=bool)  # the points whose bending is on its cap (last evaluation)
        if shape.torsion is not None:
            self._torsion_rows = np.concatenate([-shape.torsion, shape.torsion], axis=1).reshape(n, 2 * m * d)

    def _sides(self, u: np.ndarray) -> np.ndarray:
        """The cells' nodal displacements (n, 2, m, dim) [m]: minus side, plus side."""
        m = self._cells.shape[1] // 2  # not -1: a rank may hold no cells
        return u[self.jump_dofs].reshape(self.points.n, 2, m, self.dim)

    def jumps(self, u: np.ndarray) -> np.ndarray:
        """Global-frame mean jumps of the cells (n_pts, dim) [m]."""
        s = self._sides(u)
        return np.einsum("pa,pai->pi", self._shape.share, s[:, 1] - s[:, 0])

    def normal_jumps(self, u: np.ndarray) -> np.ndarray:
        """The normal jumps g_a of each cell's node pairs (n_pts, m) [m]."""
        return np.einsum("paj,pj->pa", self._normal_rows, u[self.jump_dofs])

    def twists(self, u: np.ndarray) -> np.ndarray:
        """Each face's relative rotation about its normal, (b . J) / I (n_pts,) [rad] (3D)."""
        assert self._torsion_rows is not None and self._shape.polar is not None
        return np.einsum("pj,pj->p", self._torsion_rows, u[self.jump_dofs]) / self._shape.polar

    def moment_energies(self, u: np.ndarray) -> np.ndarray:
        """Each cell's moment energy, bending k/2 (g - g_p)^T S (g - g_p) and torsion k_t/2 I twist^2 [J/m in
        2D, J in 3D]."""
        g = self.normal_jumps(u) - self.bend_plastic
        out = 0.5 * self.rotation_stiffness * np.einsum("pa,pab,pb->p", g, self._shape.bending, g)
        if self._torsion_rows is not None:
            assert self._shape.polar is not None
            out += 0.5 * self.torsion_stiffness * self._shape.polar * self.twists(u) ** 2
        return out

    def moment_energy(self, u: np.ndarray) -> float:
        """The moments' elastic energy [J/m, J]."""
        return float(np.sum(self.moment_energies(u)))

    def elastic_energy(self, u: np.ndarray) -> float:
        """The law's stored energy at the points and the moments' [J/m, J]."""
        return super().elastic_energy(u) + self.moment_energy(u)  # type: ignore[misc]

    def _cap(self, state: np.ndarray) -> np.ndarray:
        """The bending's cap C = max(0, chi - T_n) [Pa] at states (k, n_state)."""
        return np.maximum(self._strength(state) - state[:, self.dim - 1], 0.0)

    def _states_at(self, idx: np.ndarray, djump: np.ndarray, lam: np.ndarray | None) -> np.ndarray:
        """The trial states (k, n_state) of the points idx at mean-jump increments djump (k, dim) [m] (and
        multipliers lam (k, dim) [Pa], RP) in the global frame, by the group's own update (the EP and RP
        groups')."""
        raise NotImplementedError

    def _strength(self, state: np.ndarray) -> np.ndarray:
        """The law's tensile strength chi [Pa] at states (k, n_state)."""
        return self.law.records(state)[self.law.tensile_record]  # type: ignore[attr-defined]

    def _differenced(self, idx: np.ndarray, of, djump: np.ndarray, lam: np.ndarray | None,
                     lam_too: bool) -> tuple[np.ndarray, np.ndarray | None]:
        """Forward differences of of(state) (k,) at the points idx in the global components of their
        mean-jump increments djump (k, dim) and, with lam_too, of their multipliers lam (k, dim): (k, dim)
        each [per m, per Pa], from this iterate's value of(self.trial[idx]); steps of FD_STEP of the
        law's strength (over the penalty or augmentation for the jumps)."""
        law, d = self.law, self.dim  # type: ignore[attr-defined]
        k = max(law.kn or 0.0, getattr(self, "aug", 0.0))
        h = self.FD_STEP * law.scale
        base = of(self.trial[idx])  # type: ignore[attr-defined]
        by_jump = np.empty((idx.size, d))
        for i in range(d):
            dj = djump.copy()
            dj[:, i] += h / k
            by_jump[:, i] = (of(self._states_at(idx, dj, lam)) - base) / (h / k)
        if not lam_too:
            return by_jump, None
        assert lam is not None
        by_lam = np.empty((idx.size, d))
        for i in range(d):
            dl = lam.copy()
            dl[:, i] += h
            by_lam[:, i] = (of(self._states_at(idx, djump, dl)) - base) / h
        return by_jump, by_lam

    def _cap_gradient(self, idx: np.ndarray, u: np.ndarray, u_n: np.ndarray) -> np.ndarray:
        """dC/d(the cell's dofs) (k, rows) at the points idx (C = chi - T_n > 0 there). EP: dT_n/dJ from the
        law's consistent tangent, dchi/dJ by differences of the group's own update (the law's return,
        rescued, viscous) at its plastic points (elsewhere chi does not move); RP: both by differences in
        the jump and the multipliers, T_n depending on both."""
        d = self.dim
        djump = (self.jumps(u) - self.jumps(u_n))[idx]
        n_u = self._normal_rows.shape[2]
        mean = self._mean[idx]  # (k, dim, n_u): the mean jump's global components
        grad = np.zeros((idx.size, n_u + (d if self.rigid else 0)))
        if self.rigid:
            lam = u[self.lam_dofs[idx]]  # type: ignore[attr-defined]
            by_jump, by_lam = self._differenced(idx, self._cap, djump, lam, True)
            assert by_lam is not None
            grad[:, n_u:] = by_lam
        else:
            frame = self.points.frame[idx]
            by_jump = -np.einsum("pj,pji->pi", self.trial_tangent[idx, d - 1], frame)  # type: ignore[attr-defined]
            plastic = self.trial[idx, self.mode] == 1.0  # type: ignore[attr-defined]
            if plastic.any():
                at = idx[plastic]
                by_jump[plastic] += self._differenced(at, self._strength, djump[plastic], None, False)[0]
        grad[:, :n_u] = np.einsum("pi,pij->pj", by_jump, mean)
        return grad

    def _bending(self, u: np.ndarray, u_n: np.ndarray, fe: np.ndarray, ke: np.ndarray) -> int:
        """Add the bending's forces and tangent to the cells' rows (in place); the points whose cap
        switched (elastic to capped or back) since the last iterate."""
        c, s_mat, share = self._normal_rows, self._shape.bending, self._shape.share
        n_u, k = c.shape[2], self.rotation_stiffness
        g = self.normal_jumps(u)
        e = g - self.bend_plastic
        e -= np.einsum("pa,pa->p", share, e)[:, None]  # the zero-mean part: the corners' deviation over k
        top = np.argmax(e, axis=1) if e.size else np.zeros(0, dtype=np.int64)
        peak = k * np.take_along_axis(e, top[:, None], axis=1)[:, 0] if e.size else np.zeros(0)
        capped = np.zeros(e.shape[0], dtype=bool)
        if self.moment_cap and e.size:
            cap = self._cap(self.trial)  # type: ignore[attr-defined]
            capped = peak > cap + self.CAP_TOLERANCE * self.law.scale  # type: ignore[attr-defined]
        ks = k * s_mat
        stiff = np.einsum("pai,paj->pij", c, np.einsum("pab,pbj->paj", ks, c))
        beta = np.ones(e.shape[0])
        if capped.any():  # e scaled to the cap, relaxed as the law is (Duvaut-Lions: a = 1 without viscosity)
            a = self.blend() if self.viscosity > 0.0 else 1.0  # type: ignore[attr-defined]
            i = np.flatnonzero(capped)
            beta[i] = 1.0 - a + a * cap[i] / peak[i]
            e_top = peak[i] / k
            proj = np.eye(e.shape[1])[None] - share[i][:, None, :] * np.ones(e.shape[1])[None, :, None]
            row = proj[np.arange(i.size), top[i]]  # d e_top / d g
            dq = (a * cap[i] / e_top)[:, None, None] * np.einsum(
                "pab,pbc->pac", s_mat[i], proj - e[i][:, :, None] * row[:, None, :] / e_top[:, None, None])
            dq += (1.0 - a) * ks[i]
            stiff[i] = np.einsum("pai,paj->pij", c[i], np.einsum("pab,pbj->paj", dq, c[i]))
            dq_dc = a * np.einsum("pab,pb->pa", s_mat[i], e[i]) / e_top[:, None]
            ke[i, :n_u, :] += np.einsum("pai,pa,pj->pij", c[i], dq_dc, self._cap_gradient(i, u, u_n))
        e_new = beta[:, None] * e
        q = k * np.einsum("pab,pb->pa", s_mat, e_new)
        self._bend_trial = self.bend_plastic + (1.0 - beta)[:, None] * e  # the plastic part grows by what the cap removed
        self._force_trial = q
        switched = int(np.count_nonzero(capped != self.capped))
        self.capped = capped
        fe[:, :n_u] += np.einsum("paj,pa->pj", c, q)
        ke[:, :n_u, :n_u] += stiff
        return switched

    def _facet_rows(self, ev: Evaluation, u: np.ndarray, u_n: np.ndarray) -> Evaluation:
        src, share = self._source, self._share
        n_u = self._normal_rows.shape[2]
        fe = ev.fe[:, src] * share
        ke = ev.ke[:, src[:, None], src[None, :]] * share[:, :, None] * share[:, None, :]
        switched = self._bending(u, u_n, fe, ke)
        if self._torsion_rows is not None:
            assert self._shape.polar is not None
            r = self._torsion_rows
            kt = self.torsion_stiffness / self._shape.polar
            fe[:, :n_u] += (kt * np.einsum("pj,pj->p", r, u[self.jump_dofs]))[:, None] * r
            ke[:, :n_u, :n_u] += kt[:, None, None] * r[:, :, None] * r[:, None, :]
        return replace(ev, fe=fe, ke=ke, n_switched=ev.n_switched + switched)

    def bending_energy(self) -> float | None:
        """The plastic bending's work sum q . dg_p over the committed steps [J/m, J] (part of D_dissipated)."""
        return self.moment_dissipated

    def begin_step(self) -> None:
        super().begin_step()  # type: ignore[misc]
        self._bend_trial[:] = self.bend_plastic
        self._force_trial[:] = self.bend_force

    def commit(self) -> None:
        """The law's commit, and the bending's: its plastic part, and its dissipation q . dg_p
        (trapezoidal, as the law's work)."""
        dgp = self._bend_trial - self.bend_plastic
        mean = 0.5 * (self._force_trial + self.bend_force)
        spent = float(np.einsum("pa,pa->", mean, dgp))
        self.moment_dissipated += spent
        self.dissipated += spent
        self.bend_plastic[:] = self._bend_trial
        self.bend_force[:] = self._force_trial
        super().commit()  # type: ignore[misc]

    def jump_measure(self, n_dofs: int) -> Measure:
        """The nodal points' path measure on the cells' mean jumps."""
        pts, d = self.points, self.dim
        m = self.flow_directions() * (pts.weight / pts.weight.sum())[:, None]  # type: ignore[attr-defined]
        per_node = self._shape.share[:, :, None] * m[:, None, :]  # (n, m, d)
        grad = np.zeros(n_dofs)
        rows = np.concatenate([-per_node, per_node], axis=1).reshape(self.jump_dofs.shape)
        np.add.at(grad, self.jump_dofs, rows)

        def measure(u: np.ndarray) -> tuple[float, np.ndarray]:
            return float(np.sum(m * self.jumps(u))), grad

        return measure

    def evaluate(self, u: np.ndarray, u_n: np.ndarray) -> Evaluation:
        """The nodal points' evaluation at the cells' mean jumps, on the cells' nodes, with the moments."""
        return self._facet_rows(super().evaluate(u, u_n), u, u_n)  # type: ignore[misc]

    def separated(self, fraction: float) -> tuple[np.ndarray, float]:
        """The separated cells' split node pairs (k, 2), all of each cell's (a separated point parts its
        whole edge or face), and their length [m] or area [m^2]."""
        hit = self.law.separated(self.state, fraction)  # type: ignore[attr-defined]
        m = self._cells.shape[1] // 2
        pairs = np.stack([self._cells[hit, :m], self._cells[hit, m:]], axis=2).reshape(-1, 2)
        return pairs[pairs[:, 0] != pairs[:, 1]], float(self.points.weight[hit].sum())


BENDING_STATE = ("bend_plastic", "bend_force", "moment_dissipated")  # the bending's committed state


class FacetEP(_OnFacets, CohesiveEP):
    """EP surfaces with one point per interface cell (the moments' k: the law's kn, and kt for the torsion)."""

    def __init__(self, cells: np.ndarray, nodes: np.ndarray, law: TractionLaw | Law3D, *, name: str = "cohesive",
                 viscosity: float = 0.0, index: np.ndarray | None = None):
        points, shape = facet_points(nodes, cells, index)
        super().__init__(points, law, name=name, viscosity=viscosity)
        assert law.kn is not None and law.kt is not None
        self.rotation_stiffness, self.torsion_stiffness = float(law.kn), float(law.kt)
        self._on_facets(points.segments, shape, multipliers=False)

    checkpoint_attrs = CohesiveEP.checkpoint_attrs + BENDING_STATE

    def _states_at(self, idx: np.ndarray, djump: np.ndarray, lam: np.ndarray | None) -> np.ndarray:
        """The trial states (k, n_state) of the points idx at mean-jump increments djump (k, dim) [m]
        (global), by the group's own update (the law's return, rescued; viscous), nothing of the group
        changed."""
        pts, law, k, d = self.points, self.law, idx.size, self.dim
        s_new, d_new = self.trial[idx], self.trial_tangent[idx]
        fe, ke, status = np.empty((k, 2 * d)), np.empty((k, 2 * d, 2 * d)), np.zeros(k, dtype=np.int64)
        frame, weight = pts.frame[idx], pts.weight[idx]
        law.ep_points(frame, weight, djump, self._committed_for_return()[idx], self.tangent[idx], s_new, d_new,
                      fe, ke, status)
        if self.viscosity > 0.0:
            assert law.kt is not None and law.kn is not None
            duvaut_lions_points(frame, weight, djump, self.state[idx], s_new, d_new, self.blend(), float(law.kt),
                                float(law.kn), np.int64(law.dgamma_slot), np.int64(self.mode), np.empty((k, d)),
                                fe, ke)
        return s_new


class FacetRP(_OnFacets, CohesiveRP):
    """RP surfaces with one point per interface cell (the moments' k: the augmentation r). No junction
    term: a facet point closes no ring of pairs round a node."""

    rings = False

    def __init__(self, cells: np.ndarray, nodes: np.ndarray, law: TractionLaw | Law3D, augmentation: float, *,
                 name: str = "cohesive", viscosity: float = 0.0, index: np.ndarray | None = None):
        points, shape = facet_points(nodes, cells, index)
        super().__init__(points, law, augmentation, junction=np.zeros(points.n, dtype=bool), name=name,
                         viscosity=viscosity)
        self.rotation_stiffness = self.torsion_stiffness = float(augmentation)
        self._on_facets(points.segments, shape, multipliers=True)

    checkpoint_attrs = CohesiveRP.checkpoint_attrs + BENDING_STATE

    def _states_at(self, idx: np.ndarray, djump: np.ndarray, lam: np.ndarray | None) -> np.ndarray:
        """The trial states (k, n_state) of the points idx at mean-jump increments djump (k, dim) [m] and
        multipliers lam (k, dim) [Pa] (global), by the group's own update from this iterate's modes and
        pins (the augmented return, rescued; viscous), nothing of the group changed."""
        assert lam is not None
        pts, law, k, d = self.points, self.law, idx.size, self.dim
        s_new, d_new = self.trial[idx], self.trial_tangent[idx]
        fe, ke = np.empty((k, 3 * d)), np.empty((k, 3 * d, 3 * d))
        status, switched = np.zeros(k, dtype=np.int64), np.zeros(k, dtype=np.int64)
        frame, weight, eps = pts.frame[idx], pts.weight[idx], self.eps[idx]
        committed = self._committed_for_return()[idx]
        law.rp_points(frame, weight, djump, lam, self.aug, eps, self._pinned[idx], committed, self.tangent[idx],
                      self.trial[idx, self.mode], s_new, d_new, fe, ke, status, switched)
        if self.viscosity > 0.0:
            duvaut_lions_rp_points(frame, weight, djump, lam, self.aug, eps, committed, s_new, d_new, self.blend(),
                                   np.int64(law.dgamma_slot), np.int64(self.mode), np.empty((k, d)), fe, ke)
        return s_new

    def redundant_extras(self, dirichlet: np.ndarray) -> np.ndarray:
        """Multiplier dofs whose mean jump the Dirichlet conditions hold: every node of the cell held in
        that component."""
        d = self.dim
        held = np.isin(self.jump_dofs, dirichlet)
        out = [self.lam_dofs[np.all(held[:, a::d], axis=1), a] for a in range(d)]
        return np.concatenate(out).astype(np.int64)
