"""The Python API: a case from keyword sections (the same objects a case file serialises, with
the same validation and messages), a run with an optional progress display, and its results as
arrays.

Example::

    import rockfrac as rf

    case = rf.make_case(
        mesh={"kind": "block", "width": 1.0, "height": 2.0, "nx": 4, "ny": 8},
        bulk={"E": 1e9, "nu": 0.25},
        stages=[{"name": "load", "steps": 2, "displacement": {"bottom": {"y": 0.0}, "left": {"x": 0.0}},
                 "pressure": {"top": 1e6}}],
    )
    result = rf.run(case, "out/block", fields_every=1)
    result.history["R_bottom_y"][-1]       # 1e6 N/m: the support carries the pressure
    result.cell_stress(step=1)             # the stresses half-way (fields kept every step)
"""

from __future__ import annotations

import tempfile
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import BaseModel

from rockfrac.case.build import Built
from rockfrac.case.schema import Case, load_case, parse_case
from rockfrac.errors import CaseError
from rockfrac.output.csvout import read_csv
from rockfrac.output.observers import Observer, Step
from rockfrac.runner import RunSummary, run_case


def make_case(source: Mapping[str, Any] | None = None, **sections: Any) -> Case:
    """A validated case from a dict (as a TOML file would give) and/or keyword sections
    (``mesh=...``, ``bulk=...``, ``stages=[...]``...); CaseError naming the key, as for files."""
    data = dict(source or {})
    data.update({k: v for k, v in sections.items()})
    return parse_case(_plain(data), "<python case>")


def _plain(value: Any) -> Any:
    """Sections given as schema objects become dicts (so a case can mix both)."""
    if isinstance(value, BaseModel):
        return value.model_dump(mode="json", exclude_none=True)
    if isinstance(value, Mapping):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    return value


def load(path: str | Path) -> Case:
    """A validated case from a case file (TOML)."""
    return load_case(path)


@dataclass(frozen=True)
class Snapshot:
    """The fields of one converged step: nodal displacements (n_nodes, dim) [m] and cell-averaged
    stresses (n_cells, 6) [Pa] (xx, yy, zz, xy, yz, xz)."""

    displacement: np.ndarray
    cell_stress: np.ndarray


def cell_stress_of(built: Built, u: np.ndarray) -> np.ndarray:
    """Cell-averaged stresses (n_cells, 6) [Pa] of the bulk groups at their committed state."""
    out = np.zeros((built.mesh.cells.shape[0], 6))
    for g in built.bulks:
        out[g.cell_ids] = g.stresses(u).mean(axis=1)
    return out


class _Snapshots(Observer):
    """Keeps the fields of every ``every``-th converged step (by step number)."""

    def __init__(self, built: Built, every: int, store: dict[int, Snapshot]):
        self.built, self.every, self.store = built, every, store

    def step(self, step: Step) -> None:
        if step.info.step % self.every == 0:
            mesh = self.built.mesh
            u = step.info.u
            self.store[step.info.step] = Snapshot(u[: mesh.dim * mesh.n_nodes].reshape(-1, mesh.dim).copy(),
                                                  cell_stress_of(self.built, u))


@dataclass
class Result:
    """What a run left: its folder, history and point records as arrays, the built model, and the
    fields of the steps kept (``fields_every`` of :func:`run`)."""

    out: Path
    summary: RunSummary
    history: dict[str, np.ndarray]
    points: dict[str, np.ndarray] | None
    snapshots: dict[int, Snapshot] = field(default_factory=dict)  # step -> its fields
    _keep: Any = field(default=None, repr=False)  # a temporary folder, kept alive with the result

    @property
    def completed(self) -> bool:
        """The program ran to its end (or to a stop rule)."""
        return self.summary.result.completed

    @property
    def message(self) -> str:
        return self.summary.result.message

    @property
    def built(self) -> Built:
        """The mesh, model and program the run used (its state is the last converged step's)."""
        assert self.summary.built is not None
        return self.summary.built

    @property
    def u(self) -> np.ndarray:
        """The last converged displacement vector (and multipliers)."""
        return self.summary.result.u

    def displacement(self, step: int | None = None) -> np.ndarray:
        """Nodal displacements (n_nodes, dim) [m] at a kept step (None: the last converged step)."""
        if step is not None:
            return self.snapshot(step).displacement
        mesh = self.built.mesh
        return self.u[: mesh.dim * mesh.n_nodes].reshape(-1, mesh.dim)

    def cell_stress(self, step: int | None = None) -> np.ndarray:
        """Cell-averaged stresses (n_cells, 6) [Pa] (xx, yy, zz, xy, yz, xz) at a kept step (None:
        the last converged step)."""
        if step is not None:
            return self.snapshot(step).cell_stress
        return cell_stress_of(self.built, self.u)

    def snapshot(self, step: int) -> Snapshot:
        """The fields of a kept step; KeyError naming the kept steps otherwise."""
        if step not in self.snapshots:
            kept = sorted(self.snapshots)
            listed = (f"steps {kept[0]}..{kept[-1]} every {kept[1] - kept[0] if len(kept) > 1 else 1}"
                      if kept else "none (run with fields_every = n to keep every n-th step)")
            raise KeyError(f"step {step}: its fields were not kept; kept: {listed}")
        return self.snapshots[step]

    def to_pandas(self):
        """The history as a pandas DataFrame (needs pandas)."""
        import pandas as pd  # optional

        return pd.DataFrame(self.history)


def run(case_: Case | str | Path, out: str | Path | None = None, *, overwrite: bool = False, resume: bool = False,
        progress: bool | Callable[[dict], None] = False, fields_every: int = 0) -> Result:
    """Run a case (an object from :func:`make_case` or a case file) into ``out`` (None: a temporary folder
    that lives as long as the result) and return its results. progress: True for a progress line
    per step on the terminal, or a callable receiving each history row. fields_every: keep the
    displacement and stress fields of every n-th step in memory (0: only the last step's)."""
    if isinstance(fields_every, bool) or not isinstance(fields_every, int) or fields_every < 0:
        raise CaseError(f"run: fields_every = {fields_every!r}: a whole number of steps >= 0 (0: none kept)")
    keep = None
    if out is None:
        keep = tempfile.TemporaryDirectory(prefix="rockfrac-")
        out = Path(keep.name) / "run"
    callback = None
    if callable(progress):
        callback = progress
    elif progress:
        from rich.console import Console

        console = Console(stderr=True)

        def callback(row: dict) -> None:
            console.print(f"step {row['step']:4d} {row['stage']:<12s} lf={row['load_factor']:.4f} "
                          f"it={row['newton_iterations']}", highlight=False, markup=False)
    if isinstance(case_, (str, Path)):
        case_ = load_case(case_)
    snapshots: dict[int, Snapshot] = {}

    def watch(built: Built) -> list[Observer]:
        return [_Snapshots(built, fields_every, snapshots)] if fields_every else []

    summary = run_case(case_, out, progress=callback, overwrite=overwrite, resume=resume, watch=watch)
    folder = Path(out)
    points = read_csv(folder / "points.csv") if (folder / "points.csv").exists() else None
    return Result(folder, summary, read_csv(folder / "history.csv"), points, snapshots, keep)


__all__ = ["CaseError", "Result", "Snapshot", "load", "make_case", "run"]
