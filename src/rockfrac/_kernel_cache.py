"""Where Numba caches rockfrac's compiled kernels: one directory per version of the sources.

Numba's ``cache=True`` checks only the timestamp of the file that defines a kernel, not of the
kernels it calls (and inlines) from other modules: after an edit of ``laws/cohesive.py`` the cached
``laws/drive.py`` kernels would still run the old law. Keying the cache directory on a hash of every
source file of the package makes any change recompile every kernel once (all files, not only
those with kernels: a kernel also freezes the integer constants it reads from other modules, such
as the state slots of ``laws/cohesive_params.py``). ``NUMBA_CACHE_DIR`` in the
environment wins (Numba then uses it as given).
"""

from __future__ import annotations

import hashlib
import os
import shutil
from pathlib import Path

PACKAGE = Path(__file__).resolve().parent
KEEP = 3  # cache directories of earlier source versions kept next to the current one


def source_hash(root: Path = PACKAGE) -> str:
    """SHA-1 (16 hex digits) of the relative paths and contents of every .py file under root."""
    h = hashlib.sha1()
    for f in sorted(root.rglob("*.py")):
        h.update(f.relative_to(root).as_posix().encode())
        h.update(f.read_bytes())
    return h.hexdigest()[:16]


def cache_root() -> Path:
    """$XDG_CACHE_HOME/rockfrac/numba (default ~/.cache/rockfrac/numba)."""
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "rockfrac" / "numba"


def kernel_cache_dir(root: Path = PACKAGE) -> Path:
    """The cache directory of the current sources under :func:`cache_root`."""
    return cache_root() / source_hash(root)


def _prune(current: Path) -> None:
    """Remove all but the KEEP most recently used directories of older source versions."""
    try:
        old = sorted((d for d in current.parent.iterdir() if d.is_dir() and d != current),
                     key=lambda d: d.stat().st_mtime, reverse=True)
    except OSError:
        return
    for d in old[KEEP:]:
        shutil.rmtree(d, ignore_errors=True)


def configure() -> Path | None:
    """Point Numba's cache at :func:`kernel_cache_dir` (before any kernel is defined); None if the
    user set NUMBA_CACHE_DIR or the directory cannot be created (Numba then uses its default)."""
    if os.environ.get("NUMBA_CACHE_DIR"):
        return None
    target = kernel_cache_dir()
    try:
        target.mkdir(parents=True, exist_ok=True)
        os.utime(target)
    except OSError:
        return None
    _prune(target)
    import numba

    numba.config.CACHE_DIR = str(target)  # type: ignore[attr-defined]
    return target
