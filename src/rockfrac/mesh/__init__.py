"""Meshes: node and cell arrays with named node/edge groups; specimen generators."""

from rockfrac.mesh.interfaces import insert_interfaces, internal_edges
from rockfrac.mesh.mesh import Mesh
from rockfrac.mesh.specimen import cracked_specimen, hex_specimen

__all__ = ["Mesh", "cracked_specimen", "hex_specimen", "insert_interfaces", "internal_edges"]
