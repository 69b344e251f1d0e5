"""The paper's Table 1 and the specimen of Sect. 7 (as reconstructed in PAPER_NOTES.md), as case dictionaries."""

from __future__ import annotations

import math

# Table 1, CSE columns (RP values; the EP k = 1e8 variant lowers alpha_chi, alpha_c to 2e2)
CSE_LAW = {
    "GfI": 1e4, "GfII": 1e4, "chi_p": 15680.0, "chi_r": 0.0, "c_p": 9053.0, "c_r": 0.0,
    "phi_p": 0.5236, "phi_r": 0.0, "psi_p": 0.087, "alpha_chi": 2e3, "alpha_c": 2e3,
    "alpha_phi": 9e2, "alpha_psi": 9e2,
}
BULK = {"E": 1.5e7, "nu": 0.3}
CONFINEMENT = 2e4  # [Pa]
CRACK_ANGLE = math.radians(60.0)  # placeholder until the EDE bifurcation angle (issue 3)


def cse_case(form: str, k: float | None = None, alpha: float = 2e3, *, axial_displacement: float = 4e-3,
             axial_steps: int = 400, control: str = "displacement", title: str = "") -> dict:
    """A paper CSE case: the specimen, Table 1's law with alpha_chi = alpha_c = alpha."""
    coh = dict(CSE_LAW, form=form, alpha_chi=alpha, alpha_c=alpha)
    if form == "ep":
        coh.update(kn=k, kt=k)
    return {
        "title": title,
        "mesh": {"kind": "specimen", "width": 0.04, "height": 0.08, "crack": True,
                 "crack_angle": CRACK_ANGLE, "nx": 1, "ny": 1},
        "bulk": dict(BULK),
        "cohesive": coh,
        "loading": {"confinement": CONFINEMENT, "confinement_steps": 2,
                    "axial_displacement": axial_displacement, "axial_steps": axial_steps,
                    "control": control},
    }


def paper_cse_cases(**kw) -> dict[str, dict]:
    """The three CSE cases of Fig. 5: EP k = 1e9 (alpha 2e3), EP k = 1e8 (alpha 2e2), RP."""
    return {
        "EP CSE k=1e9": cse_case("ep", 1e9, 2e3, title="EP CSE, kn = kt = 1e9 Pa/m", **kw),
        "EP CSE k=1e8": cse_case("ep", 1e8, 2e2, title="EP CSE, kn = kt = 1e8 Pa/m", **kw),
        "RP CSE": cse_case("rp", title="RP CSE", **kw),
    }
