"""Rigid-plastic pairs at a junction (a node split into 3 copies or more): the reference traction of
their perturbed-Lagrangian multiplier rows (rockfrac.elements.cse_groups.CohesiveRP)."""

import numpy as np

from rockfrac.elements.cse_groups import CohesiveRP
from rockfrac.elements.interface_points import InterfacePoints
from rockfrac.laws.mohr_coulomb_surface import MohrCoulombParameters, MohrCoulombSurface
from rockfrac.laws.traction_law import MODE_PLASTIC

LAW = dict(GfI=20.0, GfII=40.0, chi_p=5600.0, chi_r=0.0, c_p=4200.0, c_r=0.0, phi_p=0.5236, phi_r=0.3,
           psi_p=0.05, alpha_chi=200.0, alpha_c=200.0, alpha_phi=50.0, alpha_psi=50.0)


def frames(angles):
    """Rotations global -> local, rows (t, n), of surfaces whose tangent makes ``angles`` with x."""
    c, s = np.cos(angles), np.sin(angles)
    return np.stack([np.stack([c, s], axis=1), np.stack([-s, c], axis=1)], axis=1)


def test_a_held_junction_pair_is_drawn_to_its_committed_traction_then_to_its_last_return():
    """Three pairs, the first two at a junction. Held shut, a junction pair's multiplier row is
    -eps w (lambda - R^T T_ref), the other pair's zero (its jump is zero): T_ref is the committed
    traction, until an iterate of the step finds the pair plastic; from then on T_ref is the traction
    that iterate returned to its surface, the committed one again at the next step."""
    law = MohrCoulombSurface(MohrCoulombParameters(**LAW))
    frame = frames(np.array([0.3, 1.2, 2.5]))

    def rot(i, t):
        """Point i's local vector t in the global frame, R_i^T t."""
        return frame[i].T @ t

    w = np.array([0.5, 0.7, 0.9])
    pts = InterfacePoints(minus=np.arange(3), plus=np.arange(3, 6), weight=w, frame=frame, x=np.zeros((3, 2)),
                          cell=np.arange(3))
    g = CohesiveRP(pts, law, 1e12, junction=np.array([True, True, False]))
    g.set_offset(12)
    t0 = np.array([[100.0, -2000.0], [-300.0, -1000.0], [50.0, -500.0]])  # committed, inside the surface
    g.state[:, :2] = t0
    g.begin_step()
    lam_l = np.array([[400.0, -1500.0], [200.0, -800.0], [-100.0, -300.0]])  # inside too
    u = np.zeros(18)
    u[g.lam_dofs] = np.array([rot(i, lam_l[i]) for i in range(3)])
    eps = g.JUNCTION_EPS
    # the rows' constraint part w (T - lambda) at a zero jump is round-off of the tractions' rotations,
    # 1e-4 of the smallest difference between the two references' terms (eps w 0.5 chi_p)
    ROUND = 1e-12 * 2000.0

    ev = g.evaluate(u, u)
    assert ev.ok and not np.any(g.trial[:, g.mode] == MODE_PLASTIC)
    for i in range(2):
        np.testing.assert_allclose(ev.fe[i, 4:], -eps * w[i] * rot(i, lam_l[i] - t0[i]), rtol=1e-9, atol=ROUND)
    np.testing.assert_allclose(ev.fe[2, 4:], 0.0, atol=ROUND)

    # an iterate with the first pair's multiplier pulling at 3 times its tensile strength: plastic
    pulled = u.copy()
    pulled[g.lam_dofs[0]] = rot(0, np.array([0.0, 3.0 * LAW["chi_p"]]))
    ev = g.evaluate(pulled, u)
    assert ev.ok and g.trial[0, g.mode] == MODE_PLASTIC and g.trial[1, g.mode] != MODE_PLASTIC
    returned = g.trial[0, :2].copy()
    assert abs(law.yield_values(g.trial[:1])[0]) <= 1e-9 * law.scale  # on its surface
    assert np.linalg.norm(returned - t0[0]) > 0.5 * LAW["chi_p"]

    # held shut again: drawn to that return, not to the committed traction
    ev = g.evaluate(u, u)
    assert g.trial[0, g.mode] != MODE_PLASTIC
    np.testing.assert_allclose(ev.fe[0, 4:], -eps * w[0] * rot(0, lam_l[0] - returned), rtol=1e-9, atol=ROUND)
    np.testing.assert_allclose(ev.fe[1, 4:], -eps * w[1] * rot(1, lam_l[1] - t0[1]), rtol=1e-9, atol=ROUND)

    # the next step starts from the committed traction again
    g.begin_step()
    ev = g.evaluate(u, u)
    np.testing.assert_allclose(ev.fe[0, 4:], -eps * w[0] * rot(0, lam_l[0] - t0[0]), rtol=1e-9, atol=ROUND)
