"""Bulk solid element groups."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rockfrac.fem import quad4
from rockfrac.fem.dofs import node_dofs


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


