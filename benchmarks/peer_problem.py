"""The cohesive problem run by rockfrac and Akantu side by side, and its closed forms (SI units).

A W x H plane-strain block of linear triangles, a straight horizontal cohesive line across at
mid-height, elastic bulk; bottom held in y, the two left corners held in x, the top edge pulled
up in equal displacement steps (mode I, uniaxial tension). The field in each half is uniform, so
every mesh gives the same force-displacement curve; it is known in closed form for both laws:

- u_top = sigma (H / E' + 1 / kn) + delta_p(sigma) with E' = E / (1 - nu^2) (uniaxial stress
  in plane strain, sigma_xx = 0) and delta_p the inelastic opening of the law at traction sigma;
- Akantu ``cohesive_bilinear`` (intrinsic): traction rises with slope kn = sigma_c / delta_0 up to
  sigma_c, then falls linearly to 0 at delta_c = 2 G_c / sigma_c; dissipated energy G_c;
- rockfrac EP CSE in pure opening: tension cap chi = chi_p exp(-alpha_chi eps_n) with
  G_f^I d eps_n = T_n d u_p, so chi(u_p) = chi_p / (1 + alpha_chi chi_p u_p / G_f^I) and the
  energy dissipated up to the plastic opening u_p is (G_f^I / alpha_chi) ln(1 + alpha_chi chi_p
  u_p / G_f^I). With alpha_chi = 1, G_f^I = G_c is dissipated when chi has fallen to chi_p / e.

Only numpy here: the module is imported by both codes' runners, each in its own virtualenv.
"""

from __future__ import annotations

import math

WIDTH = 1.0  # W [m]
HEIGHT = 1.0  # H [m]
E = 1.5e7  # Young's modulus [Pa] (paper's Gosford sandstone)
NU = 0.3
SIGMA_C = 1.0e4  # tensile strength sigma_c = chi_p [Pa]
G_C = 20.0  # mode I fracture energy [J/m^2]
KN = 1.0e9  # normal penalty stiffness [Pa/m] (paper's kn)
KT = 1.0e9  # tangential penalty stiffness [Pa/m]
ALPHA_CHI = 1.0  # rockfrac softening rate of chi [-]
STEPS_TO_PEAK = 3  # equal displacement steps up to the elastic limit
STEPS = 24  # all steps: to 8 x the peak displacement, past Akantu's full separation
TOL_RESIDUAL = 1e-8  # Newton: residual norm relative to the reaction-vector norm


def plane_strain_modulus() -> float:
    """E' = E / (1 - nu^2) [Pa]: uniaxial stress in plane strain."""
    return E / (1.0 - NU * NU)


def compliance() -> float:
    """Elastic compliance of bulk plus penalty in series per unit width, H / E' + 1 / kn [m/Pa]."""
    return HEIGHT / plane_strain_modulus() + 1.0 / KN


def peak_displacement() -> float:
    """Top displacement at the elastic limit [m]."""
    return SIGMA_C * compliance()


def step_displacements() -> list[float]:
    """Top displacement after each of the STEPS equal steps [m]."""
    du = peak_displacement() / STEPS_TO_PEAK
    return [du * (k + 1) for k in range(STEPS)]


def delta_0() -> float:
    """Akantu's elastic-limit opening sigma_c / kn [m]."""
    return SIGMA_C / KN


def delta_c() -> float:
    """Akantu's full-separation opening 2 G_c / sigma_c [m]."""
    return 2.0 * G_C / SIGMA_C


def akantu_stress(u: float) -> float:
    """Traction [Pa] of the bilinear law at top displacement u (no snap-back assumed)."""
    c = compliance()
    if u <= SIGMA_C * c:
        return u / c
    soft = (delta_c() - delta_0()) / SIGMA_C  # opening per unit traction lost [m/Pa]
    # u = sigma H/E' + delta, delta = delta_c - sigma soft
    return max(0.0, (u - delta_c()) / (HEIGHT / plane_strain_modulus() - soft))


def rockfrac_stress(u: float) -> float:
    """Traction [Pa] of the EP law in pure opening at top displacement u (continuous law)."""
    c = compliance()
    if u <= SIGMA_C * c:
        return u / c
    g = G_C / ALPHA_CHI  # u = sigma c + g (1/sigma - 1/chi_p): c s^2 - (u + g/chi_p) s + g = 0
    b = u + g / SIGMA_C
    return (b - math.sqrt(b * b - 4.0 * c * g)) / (2.0 * c)


def akantu_dissipated(u: float) -> float:
    """Energy dissipated per unit area [J/m^2] up to top displacement u (bilinear law)."""
    s = akantu_stress(u)
    if u <= SIGMA_C * compliance():
        return 0.0
    if s <= 0.0:
        return G_C
    delta = u - s * HEIGHT / plane_strain_modulus()
    return 0.5 * SIGMA_C * delta - 0.5 * s * delta  # area under the law minus the elastic return


def rockfrac_dissipated(u: float) -> float:
    """Energy dissipated per unit area [J/m^2] up to top displacement u (continuous EP law)."""
    s = rockfrac_stress(u)
    if u <= SIGMA_C * compliance():
        return 0.0
    u_p = u - s * compliance()
    g = G_C / ALPHA_CHI
    return g * math.log(1.0 + SIGMA_C * u_p / g)


def no_snap_back() -> bool:
    """Both laws soften less steeply than the bulk + penalty unloads (so no snap-back)."""
    akantu_slope = SIGMA_C / (delta_c() - delta_0())
    rockfrac_slope = ALPHA_CHI * SIGMA_C ** 2 / G_C  # at the peak, the steepest
    return max(akantu_slope, rockfrac_slope) * compliance() < 1.0


def rockfrac_discrete_stresses(displacements: list[float], work_rule: str = "backward_euler") -> list[float]:
    """Traction [Pa] after each step of rockfrac's update in pure opening, for its work rule.

    Per step: u = sigma C + u_p, G_f^I (eps - eps_old) = sigma_w (u_p - u_p_old), sigma = chi(eps)
    once the cap is reached (the update the EP return map solves); bisection on eps. sigma_w is
    sigma (backward Euler) or (sigma_s + sigma) / 2 (trapezoidal), sigma_s = chi(eps_old), the
    traction where flow starts in the step.
    """
    theta = {"backward_euler": 0.0, "trapezoidal": 0.5}[work_rule]
    c, out, eps, u_p = compliance(), [], 0.0, 0.0
    for u in displacements:
        chi = SIGMA_C * math.exp(-ALPHA_CHI * eps)
        if (u - u_p) / c <= chi:
            out.append((u - u_p) / c)
            continue
        lo, hi = eps, eps + 50.0 / ALPHA_CHI

        def gap(e: float) -> float:
            s = SIGMA_C * math.exp(-ALPHA_CHI * e)
            return G_C * (e - eps) - (theta * chi + (1.0 - theta) * s) * (u - s * c - u_p)

        for _ in range(200):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if gap(mid) < 0.0 else (lo, mid)
        eps = 0.5 * (lo + hi)
        s = SIGMA_C * math.exp(-ALPHA_CHI * eps)
        u_p = u - s * c
        out.append(s)
    return out
