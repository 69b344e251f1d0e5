"""Checkpoints of a run: the stepping position and every group's committed state, to resume from.

A checkpoint is data, never a program: a NumPy ``.npz`` archive of plain numeric and fixed-width
text arrays, read with ``allow_pickle=False`` (an object array, which only a pickle can hold, is
refused by NumPy before anything is built from it). It carries

- ``meta.format`` / ``meta.version``: what it is, in which layout (:data:`VERSION`);
- ``meta.case_sha256``: the SHA-256 of the resolved case text it was written for;
- ``meta.history_sha256``: the SHA-256 of the history rows written up to its step
  (:func:`rockfrac.output.csvout.rows_digest`), so ``--resume`` can prove that the folder's
  ``history.csv`` is the history of this checkpoint;
- ``meta.n_groups``: how many element groups it was written for (a group without state, e.g. an
  elastic solid, has no arrays of its own);
- ``meta.payload_sha256``: the SHA-256 of every other array (names, dtypes, shapes, bytes), so a
  file damaged inside an intact archive is caught too;
- ``position.*``, ``run.*`` and ``group<k>.<name>``: where the stepping is and the groups' state.

An MPI run (rockfrac.parallel) gathers nothing: every rank writes its position, with its vectors'
entries on its own local dofs (:class:`rockfrac.parallel.layout.Layout`), and its groups' state,
rank 0 into ``checkpoint.npz`` with the run's counters and ``run.ranks``, each other rank into
``checkpoint.rank<r>.npz`` (:func:`rank_file`; ``position.count`` the step it was written at). It
resumes on the same number of ranks.

It is written to a temporary file and moved into place, so a run killed at any moment leaves the
previous checkpoint intact. A truncated, corrupted, foreign or old (pickle) checkpoint is a
one-line :class:`~rockfrac.errors.CaseError`; nothing of it is used.
"""

from __future__ import annotations

import hashlib
import os
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rockfrac.errors import CaseError

FILE = "checkpoint.npz"
LEGACY = "checkpoint.pkl"  # rockfrac <= 0.1 wrote pickles: never loaded (a pickle can run code)
FORMAT = "rockfrac-checkpoint"
VERSION = 4  # 2: embedded groups keep the z-face trace of their cut hexahedra ("sections"); 3: EP cohesive
# groups keep their viscous regularisation's overstress and dissipation; 4: embedded groups keep the cells
# whose opening waits a step ("deferred"), nodal embedded cracks their cut cells


@dataclass
class Saved:
    """A checkpoint as read: position fields, run counters, per-group arrays, the hashes."""

    position: dict[str, np.ndarray]
    run: dict[str, float]
    groups: list[dict[str, np.ndarray]]
    case_sha256: str
    history_sha256: str


def text_sha256(text: str) -> str:
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def _payload_sha256(arrays: dict[str, np.ndarray]) -> str:
    h = hashlib.sha256()
    for name in sorted(arrays):
        if name == "meta.payload_sha256":
            continue
        a = np.ascontiguousarray(arrays[name])
        h.update(f"{name}|{a.dtype.str}|{a.shape}|".encode())
        h.update(a.tobytes())
    return h.hexdigest()


def rank_file(rank: int) -> str:
    """The checkpoint file of an MPI rank (rank 0's is :data:`FILE`)."""
    return FILE if rank == 0 else f"checkpoint.rank{rank}.npz"


def save(folder: Path, position: dict[str, np.ndarray], groups: list[dict[str, np.ndarray]],
         run: dict[str, float], case_sha256: str, history_sha256: str, file: str = FILE) -> Path:
    """Write folder/``file`` (checkpoint.npz) atomically (see the module docstring)."""
    arrays: dict[str, np.ndarray] = {
        "meta.format": np.array(FORMAT),
        "meta.version": np.array(VERSION, dtype=np.int64),
        "meta.case_sha256": np.array(case_sha256),
        "meta.history_sha256": np.array(history_sha256),
        "meta.n_groups": np.array(len(groups), dtype=np.int64),  # groups without state leave no arrays
    }
    for name, value in position.items():
        arrays[f"position.{name}"] = np.asarray(value)
    for name, count in run.items():
        arrays[f"run.{name}"] = np.array(float(count))
    for k, state in enumerate(groups):
        for name, value in state.items():
            a = np.asarray(value)
            if a.dtype.kind not in "biufU":
                raise TypeError(f"checkpoint: group {k} {name}: {a.dtype} is not plain data")
            arrays[f"group{k}.{name}"] = a
    arrays["meta.payload_sha256"] = np.array(_payload_sha256(arrays))
    path = Path(folder) / file
    tmp = Path(folder) / (file + ".tmp")
    with open(tmp, "wb") as fh:
        np.savez(fh, **arrays)  # type: ignore[arg-type]
        fh.flush()
        os.fsync(fh.fileno())
    os.replace(tmp, path)
    return path


def exists(folder: Path) -> bool:
    return (Path(folder) / FILE).exists()


def load(folder: Path, name: str = FILE) -> Saved | None:
    """The checkpoint ``name`` in ``folder``, or None if there is none; CaseError if it is not a valid one."""
    folder = Path(folder)
    path = folder / name
    if not path.exists():
        if name == FILE and (folder / LEGACY).exists():
            raise CaseError(f"{folder / LEGACY}: a pickle checkpoint of an older rockfrac; it is never loaded "
                            "(a pickle can run code). Rerun the case from the start")
        return None
    bad = f"{path}: not a valid rockfrac checkpoint"
    try:
        with np.load(path, allow_pickle=False) as z:
            arrays = {name: z[name] for name in z.files}
    except ValueError as err:
        why = "it holds pickled objects, which are never loaded" if "pickle" in str(err) else str(err)
        raise CaseError(f"{bad} ({why}); delete it and rerun") from None
    except (OSError, EOFError, zipfile.BadZipFile, KeyError) as err:
        raise CaseError(f"{bad} (truncated or corrupted: {err}); delete it and rerun") from None
    fmt = arrays.get("meta.format")
    if fmt is None or fmt.dtype.kind != "U" or str(fmt) != FORMAT:
        raise CaseError(f"{bad} (no '{FORMAT}' marker: written by another program)")
    version = arrays.get("meta.version")
    if version is None or version.dtype.kind != "i" or int(version) != VERSION:
        raise CaseError(f"{bad} (layout version {version!s}; this rockfrac reads version {VERSION}); rerun the case")
    digest = arrays.get("meta.payload_sha256")
    if digest is None or str(digest) != _payload_sha256(arrays):
        raise CaseError(f"{bad} (its contents do not match their checksum: corrupted); delete it and rerun")
    position = {k.removeprefix("position."): v for k, v in arrays.items() if k.startswith("position.")}
    run = {k.removeprefix("run."): float(v) for k, v in arrays.items() if k.startswith("run.")}
    groups: dict[int, dict[str, np.ndarray]] = {}
    for k, v in arrays.items():
        if k.startswith("group"):
            head, _, name = k.partition(".")
            groups.setdefault(int(head.removeprefix("group")), {})[name] = v
    n = max(groups, default=-1) + 1
    count = arrays.get("meta.n_groups")  # absent in a checkpoint of an older rockfrac (version 4 alike)
    if count is not None:
        if count.dtype.kind != "i" or int(count) < n:
            raise CaseError(f"{bad} (it counts {count!s} element groups but holds the state of {n})")
        n = int(count)
    return Saved(position, run, [groups.get(i, {}) for i in range(n)], str(arrays["meta.case_sha256"]),
                 str(arrays["meta.history_sha256"]))
