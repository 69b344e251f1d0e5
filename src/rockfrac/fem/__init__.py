"""Finite element building blocks: quadrature, shape functions, dof maps, sparse assembly."""
