"""Bulk solid element groups (Q4 plane strain or Hex8), on precomputed shape gradients."""

from __future__ import annotations

import numpy as np

from rockfrac.elements.base import Checkpointed, Evaluation
from rockfrac.fem.dofs import node_dofs
from rockfrac.fem.kinematics import elastic_assemble, elastic_blocks, element_gradients, strains
from rockfrac.fem.reference import ReferenceElement
from rockfrac.laws.elastic import elasticity, isotropic_elasticity


class SolidGeometry(Checkpointed):
    """Cells of one reference type: dofs, physical gradients (n_el, n_qp, n_nodes, dim), det J w."""

    def __init__(self, nodes: np.ndarray, cells: np.ndarray, ref: ReferenceElement):
        self.ref = ref
        self.dim = ref.dim
        self.cells = cells
        self.grads, self.wdet = element_gradients(nodes[cells], ref)
        bad = np.flatnonzero((self.wdet <= 0.0).any(axis=1))
        if bad.size:
            raise ValueError(f"inverted or degenerate {ref.name} cells {bad[:5].tolist()} (det J <= 0)")
        self.dofs = node_dofs(cells, self.dim)

    def strains(self, u: np.ndarray) -> np.ndarray:
        """Full Voigt strains (n_el, n_qp, 6) at the Gauss points."""
        return strains(self.grads, np.ascontiguousarray(u[self.dofs]))


class ElasticSolid(SolidGeometry):
    """Linear elastic bulk (plane strain in 2D); its stiffness is constant and assembled once."""

    constant = True
    n_extra = 0

    def __init__(self, nodes: np.ndarray, cells: np.ndarray, ref: ReferenceElement, E: float, nu: float):
        super().__init__(nodes, cells, ref)
        self.E, self.nu = E, nu
        self.d = elasticity(E, nu, self.dim)

    @property
    def ke(self) -> np.ndarray:
        """Element stiffness matrices (n_el, nd, nd) [N/m] (made on request: the model assembles with
        :meth:`assemble_into`, which never holds them all)."""
        return elastic_blocks(self.grads, self.wdet, self.d)

    def assemble_into(self, data: np.ndarray, slots: np.ndarray) -> None:
        """data[slots] += the element stiffnesses, values and scatter in one pass."""
        elastic_assemble(self.grads, self.wdet, self.d, slots, data)

    def stresses(self, u: np.ndarray) -> np.ndarray:
        """Gauss-point stresses (n_el, n_qp, 6) [Pa], Voigt (xx, yy, zz, xy, yz, xz)."""
        return self.strains(u) @ isotropic_elasticity(self.E, self.nu).T

    # constant groups have nothing to commit
    def begin_step(self) -> None: ...

    def commit(self) -> None: ...
