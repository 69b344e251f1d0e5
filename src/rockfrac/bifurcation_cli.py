"""``rockfrac bifurcation``: loss of ellipticity (paper eq. 7-8) of Drucker-Prager at a stress state.

The material file (TOML) has a ``[material]`` section (E, nu, beta, b, kappa0, H of
:class:`rockfrac.laws.drucker_prager_params.DruckerPrager`) and optionally a ``[stress]`` section
(sxx, syy, szz, sxy, syz, sxz [Pa], tension positive, and the accumulated plastic multiplier
gamma); ``--stress`` overrides it. The acoustic tensor uses the elastic-perfectly-plastic tangent
of eq. (8) with f, g at that stress, whether or not the stress is on the yield surface (the output
says which).
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np
from pydantic import Field
from rich.console import Console
from rich.table import Table

from rockfrac.case.schema import load_validated
from rockfrac.errors import CaseError
from rockfrac.values import MAX_STRESS, Coefficient, Hardening, Modulus, Strength, Stress
from rockfrac.values import Section as _Section

STRESS_KEYS = ("sxx", "syy", "szz", "sxy", "syz", "sxz")
ONSET_TOL = 1.0e-8  # |min det A / det A^e| up to this is reported as the onset (round-off)




class MaterialSection(_Section):
    """Drucker-Prager parameters (see rockfrac.laws.drucker_prager_params)."""

    E: Modulus = Field(description="Young's modulus [Pa]")
    nu: float = Field(gt=-1.0, lt=0.5, description="Poisson's ratio")
    beta: Coefficient = Field(description="friction coefficient of F [-]")
    b: Coefficient = Field(description="dilatancy coefficient of G [-]")
    kappa0: Strength = Field(description="initial strength kappa0 [Pa]")
    H: Hardening = Field(0.0, description="hardening modulus [Pa] (kappa = kappa0 + H gamma; H < 0 softens)")


class StressSection(_Section):
    """A stress state [Pa], tension positive, and the accumulated plastic multiplier."""

    sxx: Stress
    syy: Stress
    szz: Stress
    sxy: Stress = 0.0
    syz: Stress = 0.0
    sxz: Stress = 0.0
    gamma: float = Field(0.0, ge=0, le=1e3, description="accumulated plastic multiplier (sets kappa)")


class MaterialFile(_Section):
    title: str = ""
    description: str = ""
    material: MaterialSection
    stress: StressSection | None = None


def load_material(path: str | Path) -> MaterialFile:
    """Read and validate a material file; CaseError names the file, the key and what is allowed."""
    return load_validated(path, MaterialFile, "a material file")


def parse_stress(text: str) -> np.ndarray:
    """'sxx,syy,szz,sxy[,syz,sxz]' [Pa] -> Voigt (6,) stress."""
    parts = [t.strip() for t in text.split(",")]
    try:
        vals = [float(t) for t in parts]
    except ValueError:
        vals = []
    if len(vals) not in (4, 6) or not all(math.isfinite(v) and abs(v) <= MAX_STRESS for v in vals):
        raise CaseError(f"--stress: expected 4 or 6 comma-separated numbers sxx,syy,szz,sxy[,syz,sxz] in Pa, "
                        f"finite and at most {MAX_STRESS:g} in magnitude (got {text!r})")
    return np.array(vals + [0.0] * (6 - len(vals)))


def _law(path: Path, m: MaterialSection):
    from rockfrac.laws.drucker_prager_params import DruckerPrager

    try:
        return DruckerPrager(E=m.E, nu=m.nu, beta=m.beta, b=m.b, kappa0=m.kappa0, H=m.H)
    except ValueError as err:
        raise CaseError(f"{path}: [material] H: {err}") from None


def _vec(v: np.ndarray) -> str:
    return "(" + ", ".join(f"{x:+.4f}" for x in v) + ")"


def _cmd_bifurcation(args: argparse.Namespace) -> int:
    from rockfrac.laws import drucker_prager as dp
    from rockfrac.laws.bifurcation import localization_at

    path = Path(args.material)
    mf = load_material(path)
    law = _law(path, mf.material)
    gamma = 0.0
    if args.stress is not None:
        sigma = parse_stress(args.stress)
    elif mf.stress is not None:
        sigma = np.array([getattr(mf.stress, k) for k in STRESS_KEYS])
        gamma = mf.stress.gamma
    else:
        raise CaseError(f"{path}: no [stress] section and no --stress option; give the stress as "
                        "[stress] sxx, syy, szz (sxy, syz, sxz optional) in Pa "
                        "or --stress sxx,syy,szz,sxy")
    if args.plane_strain and (sigma[4] != 0.0 or sigma[5] != 0.0):
        raise CaseError(f"{path}: plane strain needs syz = sxz = 0 (got {sigma[4]:g}, {sigma[5]:g}); "
                        "use --3d")
    p = law.as_array()
    s = np.empty(6)
    pm, sn = dp.deviator(sigma, s)
    if not sn > 1.0e-12 * (abs(pm) + 1.0):
        raise CaseError(f"{path}: the stress is hydrostatic (s = 0, the cone apex): f and g of eq. (8) "
                        "are not defined there; give a stress with a deviator")
    f_val = dp.yield_value(sigma, gamma, p)
    scale = math.sqrt(1.5) * sn + math.sqrt(3.0) * (abs(law.beta * pm) + abs(law.kappa0 + law.H * gamma))
    loc = localization_at(law, sigma, plane_strain=args.plane_strain)

    out = Console(highlight=False)
    out.width = max(out.width, 132)
    out.print(f"[bold]rockfrac bifurcation[/] {path} ({'plane strain' if args.plane_strain else '3D'})")
    out.print(f"stress [Pa] (xx, yy, zz, xy, yz, xz) = ({', '.join(f'{x:.8g}' for x in sigma)}), "
              f"gamma = {gamma:.6g}")
    out.print(f"p = {pm:.6g} Pa, |s| = {sn:.6g} Pa, F = {f_val:.6g} Pa "
              f"(kappa = {law.kappa0 + law.H * gamma:.6g} Pa)")
    if abs(f_val) <= 1.0e-6 * scale:
        out.print("the stress is [green]on the yield surface[/] (|F| <= 1e-6 scale)")
    elif f_val < 0.0:
        out.print("the stress is [yellow]inside the yield surface[/] (elastic); eq. (8) evaluated anyway")
    else:
        out.print("the stress is [red]outside the yield surface[/] (not admissible); "
                  "eq. (8) evaluated anyway")
    table = Table(title="minima of det A(n) / det A^e(n), eq. (7)-(8)")
    for col in ("#", "normal n", "normal angle [deg]", "band angle [deg]", "det A / det A^e", "slip m",
                "asin(m.n) [deg]"):  # asin(m.n): inclination of the jump to the band (dilatancy)
        table.add_column(col, justify="right", no_wrap=True)
    for k in range(loc.normals.shape[0]):
        n, m = loc.normals[k], loc.slips[k]
        dil = math.degrees(math.asin(min(1.0, abs(float(m @ n)))))
        table.add_row(str(k + 1), _vec(n), f"{loc.normal_angles_deg[k]:.4f}",
                      f"{loc.band_angles_deg[k]:.4f}", f"{loc.ratios[k]:.6g}", _vec(m), f"{dil:.4f}")
    out.print(table)
    r = loc.min_ratio
    if abs(r) <= ONSET_TOL:
        verdict = f"[yellow]at the onset of localization[/] (|min det A / det A^e| <= {ONSET_TOL:g})"
    elif r < 0.0:
        verdict = "[red]localized[/] (min det A < 0)"
    else:
        verdict = "[green]not localized[/] (min det A > 0)"
    out.print(f"min det A / det A^e = {r:.6g}: {verdict}")
    return 0


def add_parser(subparsers) -> None:
    """Register ``rockfrac bifurcation`` on the CLI's subparsers."""
    b = subparsers.add_parser("bifurcation",
                              help="loss of ellipticity (eq. 7-8) of Drucker-Prager at a stress state")
    b.add_argument("material", type=Path,
                   help="TOML file: [material] E, nu, beta, b, kappa0, H; optional [stress]")
    b.add_argument("--stress", help="sxx,syy,szz,sxy[,syz,sxz] in Pa, tension positive, overrides "
                   "[stress]; write --stress=-2e4,... when it starts with a minus")
    mode = b.add_mutually_exclusive_group()
    mode.add_argument("--plane-strain", dest="plane_strain", action="store_true", default=True,
                      help="in-plane normals (cos t, sin t, 0) (default)")
    mode.add_argument("--3d", dest="plane_strain", action="store_false", help="all unit normals")
    b.set_defaults(func=_cmd_bifurcation)
