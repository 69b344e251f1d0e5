"""Zero-thickness cohesive surface elements with nodal integration (paper Sect. 6.1, 6.2): the point
loops of the paper's traction law (kept importable here; each law's loops live in its own module,
see rockfrac.laws.traction_law, and the pair kinematics in rockfrac.fem.interface)."""

from __future__ import annotations

from rockfrac.laws.mohr_coulomb_surface import ep_points, rp_points

__all__ = ["ep_points", "rp_points"]
