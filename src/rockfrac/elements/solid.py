"""Bulk solid element groups (Q4/T3 plane strain or Hex8), on precomputed shape gradients."""

from __future__ import annotations

import numpy as np

from rockfrac.elements.base import ElementGroup, Evaluation
from rockfrac.fem.dofs import node_dofs
from rockfrac.fem.kinematics import (
    elastic_assemble,
    elastic_blocks,
    element_gradients,
    internal_forces,
    strains,
)
from rockfrac.fem.loads import StressField, quadrature_points
from rockfrac.fem.reference import ReferenceElement
from rockfrac.laws.elastic import elasticity, isotropic_elasticity, strain_energy


class SolidGeometry:
    """Cells of one reference type: dofs, physical gradients (n_el, n_qp, n_nodes, dim), det J w.

    region: the mesh region (material) the cells belong to; cell_ids: their indices in the mesh
    (default: all cells, in order); ``whole_ids``: their indices in the whole mesh (on an MPI rank's
    piece of it, set by the builder; else cell_ids).
    """

    def __init__(self, nodes: np.ndarray, cells: np.ndarray, ref: ReferenceElement, *, region: str = "bulk",
                 cell_ids: np.ndarray | None = None):
        self.ref = ref
        self.dim = ref.dim
        self.nodes = nodes
        self.cells = cells
        self.name = self.region = region
        self.cell_ids = np.arange(cells.shape[0]) if cell_ids is None else np.asarray(cell_ids)
        self.whole_ids = self.cell_ids
        self.grads, self.wdet = element_gradients(nodes[cells], ref)
        bad = np.flatnonzero((self.wdet <= 0.0).any(axis=1))
        if bad.size:
            raise ValueError(f"inverted or degenerate {ref.name} cells {bad[:5].tolist()} (det J <= 0)")
        self.dofs = node_dofs(cells, self.dim)

    def strains(self, u: np.ndarray) -> np.ndarray:
        """Full Voigt strains (n_el, n_qp, 6) at the Gauss points."""
        return strains(self.grads, np.ascontiguousarray(u[self.dofs]))


    def quadrature_points(self) -> np.ndarray:
        """Physical coordinates (n_el, n_qp, dim) of the Gauss points [m]."""
        return quadrature_points(self.nodes, self.cells, self.ref)


class SolidGroup(SolidGeometry, ElementGroup):
    """A bulk element group: the cells of one material region (Young's modulus E, Poisson's ratio nu)."""

    E: float
    nu: float

    def initial_stress_at_points(self, stress: StressField) -> np.ndarray:
        """The in-situ stress (n_el, n_qp, 6) [Pa] at the Gauss points."""
        x = self.quadrature_points()
        return np.ascontiguousarray(stress(x.reshape(-1, self.dim)).reshape(x.shape[0], x.shape[1], 6))

    def elastic_energy(self, u: np.ndarray) -> float:
        """sum w sigma . S sigma / 2 over the Gauss points [J] (per unit thickness in 2D)."""
        return strain_energy(self.stresses(u), self.wdet, self.E, self.nu)

    def stresses(self, u: np.ndarray) -> np.ndarray:
        """Gauss-point stresses (n_el, n_qp, 6) [Pa] at the committed state."""
        raise NotImplementedError

    def cell_fields(self, u: np.ndarray) -> dict[str, np.ndarray]:
        """Per-cell fields for ParaView at the committed state: stress (n_el, 6) averaged over the
        Gauss points, plastic_strain (n_el, 6), gamma (n_el,), localized (n_el,) 0/1."""
        n = self.cells.shape[0]
        return {"stress": self.stresses(u).mean(axis=1), "plastic_strain": np.zeros((n, 6)),
                "gamma": np.zeros(n), "localized": np.zeros(n, dtype=np.int8)}

    def plastic_fraction(self) -> float | None:
        """Share of Gauss points whose last committed update was plastic (None: an elastic group)."""
        return None


class ElasticSolid(SolidGroup):
    """Linear elastic bulk (plane strain in 2D); its stiffness is constant and assembled once."""

    constant = True

    def __init__(self, nodes: np.ndarray, cells: np.ndarray, ref: ReferenceElement, E: float, nu: float, *,
                 region: str = "bulk", cell_ids: np.ndarray | None = None):
        super().__init__(nodes, cells, ref, region=region, cell_ids=cell_ids)
        self.E, self.nu = E, nu
        self.d = elasticity(E, nu, self.dim)
        self.sigma0: np.ndarray | None = None  # in-situ stress at the Gauss points (n_el, n_qp, 6) [Pa]

    def set_initial_stress(self, stress: StressField) -> None:
        self.sigma0 = self.initial_stress_at_points(stress)

    def constant_force(self) -> np.ndarray | None:
        """sum_q w B^T sigma0 (n_el, nd): the in-situ stress's share of f_int."""
        return None if self.sigma0 is None else internal_forces(self.grads, self.wdet, self.sigma0)

    @property
    def ke(self) -> np.ndarray:
        """Element stiffness matrices (n_el, nd, nd) [N/m] (made on request: the problem assembles with
        :meth:`assemble_constant`, which never holds them all)."""
        return elastic_blocks(self.grads, self.wdet, self.d)

    def assemble_constant(self, data: np.ndarray, slots: np.ndarray) -> None:
        """data[slots] += the element stiffnesses, values and scatter in one pass."""
        elastic_assemble(self.grads, self.wdet, self.d, slots, data)

    def evaluate(self, u: np.ndarray, u_n: np.ndarray) -> Evaluation:
        """fe = ke u_e (the problem assembles this group once, as a constant matrix)."""
        ke = self.ke
        return Evaluation(np.einsum("eij,ej->ei", ke, u[self.dofs]), ke)

    def stresses(self, u: np.ndarray) -> np.ndarray:
        """Gauss-point stresses (n_el, n_qp, 6) [Pa], Voigt (xx, yy, zz, xy, yz, xz): sigma0 + C eps."""
        sigma = self.strains(u) @ isotropic_elasticity(self.E, self.nu).T
        return sigma if self.sigma0 is None else sigma + self.sigma0
