"""rockfrac: quasi-static finite element fracture of rock.

Elasto-plastic (EP) and rigid-plastic (RP) cohesive surface elements and embedded strong
discontinuity elements, after Regueiro & Yu (ARMA 2010), on general rock tests.

The flat API (loaded on first use, so ``import rockfrac`` stays cheap)::

    import rockfrac as rf

    case = rf.make_case(mesh={...}, bulk={...}, stages=[...])   # or rf.load("case.toml")
    result = rf.run(case, "out/x", progress=True)
    result.history["R_top_y"], result.points, result.cell_stress()

- :func:`make_case`, :func:`load`, :func:`run`, :class:`Result`, :class:`Snapshot` (rockfrac.api);
- :class:`Case` and the section classes (rockfrac.case.schema), :class:`CaseError`;
- :func:`read_mesh` (Gmsh .msh), :class:`Mesh`, the rock-test meshes :func:`disc`,
  :func:`plate_with_hole`, :func:`notched_beam`, :func:`box`, :func:`cylinder` (rockfrac.mesh.rock_tests);
- :data:`LAWS`, the traction laws by name (rockfrac.laws.registry), and :func:`law`, one with
  its parameters (its ``drive(jumps)`` runs the material-point driver);
- :func:`localization`: the loss of ellipticity of Drucker-Prager at a stress (paper eq. 7-8).
"""

from __future__ import annotations

import importlib
from typing import Any

__version__ = "0.2.0"

from rockfrac._kernel_cache import configure as _configure_kernel_cache

KERNEL_CACHE = _configure_kernel_cache()  # before any submodule defines a Numba kernel


def _record_kernels_at_exit() -> None:
    """With ROCKFRAC_RECORD_KERNELS set to a folder, this process writes the kernel signatures it
    used there when it exits (rockfrac.precompile: how its list is made)."""
    import atexit
    import os

    folder = os.environ.get("ROCKFRAC_RECORD_KERNELS")
    if folder:
        from pathlib import Path

        from rockfrac.precompile import record

        atexit.register(record, Path(folder))


_record_kernels_at_exit()

_EXPORTS = {
    "make_case": ("rockfrac.api", "make_case"),
    "load": ("rockfrac.api", "load"),
    "run": ("rockfrac.api", "run"),
    "Result": ("rockfrac.api", "Result"),
    "Snapshot": ("rockfrac.api", "Snapshot"),
    "Case": ("rockfrac.case.schema", "Case"),
    "MeshSection": ("rockfrac.case.schema", "MeshSection"),
    "BulkSection": ("rockfrac.case.schema", "BulkSection"),
    "MaterialSection": ("rockfrac.case.schema", "MaterialSection"),
    "EmbeddedSection": ("rockfrac.case.schema", "EmbeddedSection"),
    "StageSection": ("rockfrac.case.schema", "StageSection"),
    "InitialSection": ("rockfrac.case.schema", "InitialSection"),
    "MonitorSection": ("rockfrac.case.schema", "MonitorSection"),
    "CaseError": ("rockfrac.errors", "CaseError"),
    "Mesh": ("rockfrac.mesh.mesh", "Mesh"),
    "read_mesh": ("rockfrac.mesh.gmsh_io", "read_mesh"),
    "disc": ("rockfrac.mesh.rock_tests", "disc"),
    "plate_with_hole": ("rockfrac.mesh.rock_tests", "plate_with_hole"),
    "notched_beam": ("rockfrac.mesh.rock_tests", "notched_beam"),
    "box": ("rockfrac.mesh.rock_tests", "box"),
    "cylinder": ("rockfrac.mesh.rock_tests", "cylinder"),
    "LAWS": ("rockfrac.laws.registry", "LAWS"),
    "law": ("rockfrac.api_laws", "law"),
    "localization": ("rockfrac.api_laws", "localization"),
}

__all__ = sorted(_EXPORTS) + ["KERNEL_CACHE", "__version__"]


def __getattr__(name: str) -> Any:
    if name in _EXPORTS:
        module, attr = _EXPORTS[name]
        value = getattr(importlib.import_module(module), attr)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'rockfrac' has no attribute {name!r}")


def __dir__() -> list[str]:
    return __all__
