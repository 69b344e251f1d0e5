"""Compile rockfrac's kernels ahead of a first run, on several processes at once (``rockfrac compile``).

Numba compiles a kernel on its first call, for the argument types of that call, and caches the
machine code on disk (``rockfrac._kernel_cache``). A fresh install therefore spends its first runs
compiling, one kernel after the other in each process. This module compiles every kernel for the
argument types that rockfrac's own runs pass it, listed in ``kernel_signatures.json`` beside it,
split over ``jobs`` processes: each process writes its kernels into the shared cache, and every
later process loads them from there. Only kernels with a Python entry point are listed (and both
versions of a ``parallel_kernel``): the ``inner`` functions they call are compiled with them.

The list is data, read without evaluating anything: a type is a dtype name (checked against the
numeric dtypes), or ``{"array": [dtype, ndim, layout, readonly]}``, ``{"unituple": [type, n]}``,
``{"tuple": [types...]}``, ``{"function": [return type, [argument types...]]}`` (a first-class
function, such as a traction law's trial return). It is made by running code with
``ROCKFRAC_RECORD_KERNELS`` set to a folder (every process then writes the signatures it used there
as it ends; the test suite's conftest has the pytest-xdist workers write theirs), then ``python -m
rockfrac.precompile --merge FOLDER`` (benchmarks/README.md, "The test suite's time"). A listed
signature that a kernel no longer accepts is reported, not compiled; the kernel then compiles at its
first call, as without this module.
"""

from __future__ import annotations

import importlib
import json
import os
import pkgutil
import re
import sys
import time
from collections.abc import Iterator
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from multiprocessing import get_context
from pathlib import Path
from typing import Any

LIST = Path(__file__).resolve().parent / "kernel_signatures.json"
_DTYPE = re.compile(r"^(u?int(8|16|32|64)|float(32|64)|complex(64|128)|boolean)$")
_LAYOUTS = ("C", "F", "A")


class UnknownType(ValueError):
    """A Numba type this list format does not describe (such a signature is not listed)."""


def describe(t: Any) -> Any:
    """The JSON description of a Numba argument type (see the module note)."""
    from numba.core import types

    if isinstance(t, types.Array):
        return {"array": [describe(t.dtype), t.ndim, t.layout, bool(t.mutable is False)]}
    if isinstance(t, types.UniTuple):
        return {"unituple": [describe(t.dtype), t.count]}
    if isinstance(t, types.Tuple):
        return {"tuple": [describe(e) for e in t.types]}
    if isinstance(t, types.FunctionType):  # a first-class function (a law's trial return)
        sig = t.signature
        return {"function": [describe(sig.return_type), [describe(a) for a in sig.args]]}
    if isinstance(t, types.Boolean):
        return "boolean"
    if isinstance(t, (types.Integer, types.Float, types.Complex)) and _DTYPE.match(str(t)):
        return str(t)
    raise UnknownType(f"{t!r}")


def build(d: Any) -> Any:
    """The Numba type of a JSON description; ValueError for anything else."""
    from numba.core import types

    if isinstance(d, str):
        if not _DTYPE.match(d):
            raise ValueError(f"not a numeric dtype name: {d!r}")
        return getattr(types, d)
    if isinstance(d, dict) and len(d) == 1:
        (kind, v), = d.items()
        if kind == "array" and isinstance(v, list) and len(v) == 4:
            dtype, ndim, layout, readonly = v
            if not (isinstance(ndim, int) and 0 < ndim <= 8 and layout in _LAYOUTS and isinstance(readonly, bool)):
                raise ValueError(f"bad array type: {v!r}")
            return types.Array(build(dtype), ndim, layout, readonly=readonly)
        if kind == "unituple" and isinstance(v, list) and len(v) == 2 and isinstance(v[1], int) and 0 < v[1] <= 64:
            return types.UniTuple(build(v[0]), v[1])
        if kind == "tuple" and isinstance(v, list) and len(v) <= 64:
            return types.Tuple([build(e) for e in v])
        if kind == "function" and isinstance(v, list) and len(v) == 2 and isinstance(v[1], list) and len(v[1]) <= 64:
            from numba.core.typing import signature

            return types.FunctionType(signature(build(v[0]), *[build(a) for a in v[1]]))
    raise ValueError(f"not a type description: {d!r}")


def _modules() -> Iterator[Any]:
    """Every module of the package (imported)."""
    import rockfrac

    yield rockfrac
    for info in pkgutil.walk_packages(rockfrac.__path__, "rockfrac."):
        if info.name.endswith("__main__"):
            continue
        yield importlib.import_module(info.name)


def dispatchers(loaded_only: bool = False) -> dict[str, Any]:
    """Every kernel with a Python entry point, by ``module:qualname`` (a parallel_kernel's two versions
    under their own names, the serial one ending in ``__serial``); loaded_only: only the modules
    already imported."""
    from numba.core.registry import CPUDispatcher

    from rockfrac.compiled import InnerDispatcher
    from rockfrac.threads import ParallelKernel

    mods = [m for n, m in list(sys.modules.items()) if n == "rockfrac" or n.startswith("rockfrac.")] \
        if loaded_only else list(_modules())
    found: dict[str, Any] = {}
    for mod in mods:
        for obj in list(vars(mod).values()):
            versions = [obj.serial, obj.parallel] if isinstance(obj, ParallelKernel) else [obj]
            for d in versions:
                if isinstance(d, CPUDispatcher) and not isinstance(d, InnerDispatcher) and \
                        d.py_func.__module__.startswith("rockfrac"):
                    found[f"{d.py_func.__module__}:{d.py_func.__qualname__}"] = d
    return found


def record(folder: Path) -> Path:
    """Write the signatures compiled or loaded in this process into ``folder`` (one file per process)."""
    listed: dict[str, list] = {}
    for name, d in dispatchers(loaded_only=True).items():
        sigs = []
        for sig in d.signatures:
            try:
                sigs.append([describe(t) for t in sig])
            except UnknownType:
                continue  # not listable: it compiles at its first call
        if sigs:
            listed[name] = sigs
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"kernels-{os.getpid()}.json"
    path.write_text(json.dumps(listed))
    return path


def merge(folder: Path, out: Path = LIST) -> int:
    """Join the files :func:`record` wrote into ``folder`` with the list at ``out``; the number of
    signatures listed."""
    joined: dict[str, list] = json.loads(out.read_text()) if out.exists() else {}
    for f in sorted(folder.glob("kernels-*.json")):
        for name, sigs in json.loads(f.read_text()).items():
            have = joined.setdefault(name, [])
            have.extend(s for s in sigs if s not in have)
    lines = [f"{json.dumps(name)}: {json.dumps(sigs)}" for name, sigs in sorted(joined.items())]
    out.write_text("{\n" + ",\n".join(lines) + "\n}\n")  # a kernel a line
    return sum(len(v) for v in joined.values())


@dataclass
class Compiled:
    """What one process compiled: signatures compiled (or found in the cache), those refused, seconds."""

    done: int
    refused: list[str]
    seconds: float


def _compile_part(entries: list[tuple[str, list]]) -> Compiled:
    t0 = time.perf_counter()
    kernels = dispatchers()
    done, refused = 0, []
    for name, sigs in entries:
        d = kernels.get(name)
        if d is None:
            refused.append(f"{name}: no such kernel")
            continue
        for sig in sigs:
            try:
                d.compile(tuple(build(t) for t in sig))
                done += 1
            except Exception as err:  # noqa: BLE001 (a stale entry: the kernel compiles at its first call)
                refused.append(f"{name}{tuple(sig)}: {type(err).__name__}: {str(err).splitlines()[0][:200]}")
    return Compiled(done, refused, time.perf_counter() - t0)


def load(path: Path = LIST) -> dict[str, list]:
    """The listed signatures, by kernel (checked to be type descriptions)."""
    listed = json.loads(path.read_text())
    if not isinstance(listed, dict):
        raise ValueError(f"{path}: expected an object of kernel names")
    for name, sigs in listed.items():
        for sig in sigs:
            for t in sig:
                build(t)
    return listed


def parts(listed: dict[str, list], jobs: int) -> list[list[tuple[str, list]]]:
    """The kernels split into ``jobs`` parts of about as many signatures, every signature of one
    kernel in one part (two processes never write one kernel's cache index at once)."""
    out: list[list[tuple[str, list]]] = [[] for _ in range(jobs)]
    load_of = [0] * jobs
    for name, sigs in sorted(listed.items(), key=lambda kv: -len(kv[1])):
        i = load_of.index(min(load_of))
        out[i].append((name, sigs))
        load_of[i] += len(sigs)
    return [p for p in out if p]


def compile_all(jobs: int, path: Path = LIST) -> list[Compiled]:
    """Compile every listed signature on ``jobs`` processes (spawned: each imports rockfrac afresh)."""
    split = parts(load(path), jobs)
    if len(split) <= 1:
        return [_compile_part(split[0] if split else [])]
    with ProcessPoolExecutor(len(split), mp_context=get_context("spawn")) as pool:
        return list(pool.map(_compile_part, split))


def main(argv: list[str] | None = None) -> int:
    import argparse

    p = argparse.ArgumentParser(prog="python -m rockfrac.precompile")
    p.add_argument("--merge", type=Path, required=True, help="folder of the files ROCKFRAC_RECORD_KERNELS wrote")
    args = p.parse_args(argv)
    print(f"{merge(args.merge)} signatures listed in {LIST}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
