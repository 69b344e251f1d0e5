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
    result = rf.run(case, "out/block")
    result.history["R_bottom_y"][-1]       # 1e6 N/m: the support carries the pressure
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


@dataclass
class Result:
    """What a run left: its folder, history and point records as arrays, the built model."""

    out: Path
    summary: RunSummary
    history: dict[str, np.ndarray]
    points: dict[str, np.ndarray] | None
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

    def displacement(self) -> np.ndarray:
        """Nodal displacements (n_nodes, dim) [m] at the last converged step."""
        mesh = self.built.mesh
        return self.u[: mesh.dim * mesh.n_nodes].reshape(-1, mesh.dim)

    def cell_stress(self) -> np.ndarray:
        """Cell-averaged stresses (n_cells, 6) [Pa] (xx, yy, zz, xy, yz, xz) at the last step."""
        out = np.zeros((self.built.mesh.cells.shape[0], 6))
        for g in self.built.bulks:
            out[g.cell_ids] = g.stresses(self.u).mean(axis=1)
        return out

    def to_pandas(self):
        """The history as a pandas DataFrame (needs pandas)."""
        import pandas as pd  # optional

        return pd.DataFrame(self.history)


def run(case_: Case | str | Path, out: str | Path | None = None, *, overwrite: bool = False, resume: bool = False,
        progress: bool | Callable[[dict], None] = False) -> Result:
    """Run a case (an object from :func:`make_case` or a case file) into ``out`` (None: a temporary folder
    that lives as long as the result) and return its results. progress: True for a progress line
    per step on the terminal, or a callable receiving each history row."""
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
    summary = run_case(case_, out, progress=callback, overwrite=overwrite, resume=resume)
    folder = Path(out)
    points = read_csv(folder / "points.csv") if (folder / "points.csv").exists() else None
    return Result(folder, summary, read_csv(folder / "history.csv"), points, keep)


__all__ = ["CaseError", "Result", "load", "make_case", "run"]
