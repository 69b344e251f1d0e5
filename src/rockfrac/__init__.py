"""rockfrac: quasi-static finite element fracture of rock.

Elasto-plastic (EP) and rigid-plastic (RP) cohesive surface elements and embedded
strong discontinuity elements, after Regueiro & Yu (ARMA 2010).
"""

__version__ = "0.1.0"

from rockfrac._kernel_cache import configure as _configure_kernel_cache

KERNEL_CACHE = _configure_kernel_cache()  # before any submodule defines a Numba kernel
