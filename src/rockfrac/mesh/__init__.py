"""Meshes: node and cell arrays with named node/edge groups; specimen generators."""

from rockfrac.mesh.mesh import Mesh
from rockfrac.mesh.specimen import cracked_specimen, hex_specimen

__all__ = ["Mesh", "cracked_specimen", "hex_specimen"]
