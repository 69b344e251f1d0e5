"""Row-by-row CSV writers that flush each step, so a stopped run keeps every converged step.

Fields are written by :mod:`csv` (a field holding a comma, a quote or a line break is quoted), a
real NaN as ``nan`` and an infinity as ``inf``/``-inf``; an empty cell means "not applicable"
(the column does not apply to that row). Each writer keeps a SHA-256 of the rows it holds
(:meth:`CsvWriter.digest`), which a checkpoint records so that a resumed run can prove the history
it continues is its own (:func:`rows_digest`).
"""

from __future__ import annotations

import csv
import hashlib
from pathlib import Path
from typing import Any

import numpy as np

HISTORY_COLUMNS = [
    "step", "stage", "control", "load_factor", "u_axial", "F_axial", "newton_iterations", "cutbacks",
    "jump_p_norm", "chi", "c", "tan_phi", "tan_psi", "n_plastic", "det_ratio", "n_localized", "bulk_plastic",
]
POINT_COLUMNS = [
    "step", "point", "set", "cell", "x", "y", "angle", "jump_t", "jump_n", "T_t", "T_n", "jump_p_t", "jump_p_n",
    "jump_p_norm", "eps_n_p", "eps_s_p", "chi", "c", "tan_phi", "tan_psi", "gamma", "zeta", "c_p", "state",
]
#: points.csv of a 3D model: position, unit normal, local (t1, t2, n) components
POINT_COLUMNS_3D = [
    "step", "point", "set", "cell", "x", "y", "z", "n_x", "n_y", "n_z", "jump_t1", "jump_t2", "jump_n", "T_t1", "T_t2",
    "T_n", "jump_p_t1", "jump_p_t2", "jump_p_n", "jump_p_norm", "eps_n_p", "eps_s_p", "chi", "c", "tan_phi",
    "tan_psi", "state",
]


def _fmt(v: Any) -> str:
    """A cell: '' for None (not applicable), 'nan' for a real NaN, repr of floats (round trip)."""
    if v is None:
        return ""
    if isinstance(v, (float, np.floating)):
        return repr(float(v))  # 'nan', 'inf', '-inf' included
    if isinstance(v, (np.integer,)):
        return str(int(v))
    return str(v)


def _cells(values: Any, n: int) -> list[str]:
    """The n cells of one column, as :func:`_fmt` writes them (a float array converted at once)."""
    a = np.asarray(values)
    if a.dtype.kind == "f":
        return [repr(x) for x in a[:n].tolist()]  # Python floats: repr(float(v)) of each
    return [_fmt(x) for x in a[:n].tolist()]


def _update(h: Any, row: list[str]) -> None:
    h.update(("\x1f".join(row) + "\x1e").encode("utf-8"))


def _kept_rows(path: Path, keep_steps: int) -> list[list[str]]:
    """Header and the rows with step <= keep_steps of a CSV written by :class:`CsvWriter`."""
    with open(path, newline="", encoding="utf-8") as fh:
        rows = list(csv.reader(fh))
    if not rows or "step" not in rows[0]:
        raise ValueError(f"{path}: no header with a 'step' column")
    step = rows[0].index("step")
    kept = [rows[0]]
    for r in rows[1:]:
        if not r:
            continue
        try:
            s = int(float(r[step]))
        except (ValueError, IndexError):
            break  # a row cut by a kill mid-write: nothing after it is kept
        if s <= keep_steps:
            kept.append(r)
    return kept


def _widened(path: Path, rows: list[list[str]], columns: list[str]) -> list[list[str]]:
    """The kept rows under the header ``columns``, a column the old header lacks empty; ValueError if the old
    header has a column that ``columns`` has not (another run's file)."""
    old = rows[0]
    lost = [c for c in old if c not in columns]
    if lost:
        raise ValueError(f"{path}: its columns {lost} are not this run's: written by another case")
    at = [old.index(c) if c in old else -1 for c in columns]
    return [columns] + [[r[i] if 0 <= i < len(r) else "" for i in at] for r in rows[1:]]


def rows_digest(path: str | Path, keep_steps: int) -> str:
    """SHA-256 of the header and the rows with step <= keep_steps, as :meth:`CsvWriter.digest`
    computes it while writing; ValueError if the file has no header with a step column."""
    h = hashlib.sha256()
    for r in _kept_rows(Path(path), keep_steps):
        _update(h, r)
    return h.hexdigest()


class CsvWriter:
    """A CSV file with a fixed header; ``write`` appends rows and flushes."""

    def __init__(self, path: Path, columns: list[str], keep_steps: int | None = None):
        """A new file, or (keep_steps) the existing one cut to its rows with step <= keep_steps and
        appended to (a resumed run)."""
        self.columns = columns
        self._hash = hashlib.sha256()
        rows = _kept_rows(Path(path), keep_steps) if keep_steps is not None and Path(path).exists() else [columns]
        if rows[0] != columns:  # resumed by a rockfrac that writes more columns: the old rows get empty cells
            rows = _widened(Path(path), rows, columns)
        self._fh = open(path, "w", newline="", encoding="utf-8")
        self._csv = csv.writer(self._fh)
        for r in rows:
            self._row(r)
        self._fh.flush()

    def _row(self, cells: list[str]) -> None:
        self._csv.writerow(cells)
        _update(self._hash, cells)

    def write(self, row: dict[str, Any]) -> None:
        self._row([_fmt(row.get(c)) for c in self.columns])
        self._fh.flush()

    def write_many(self, rows: dict[str, np.ndarray], n: int) -> None:
        """Append the first n rows of the columns ``rows`` (a column it lacks: empty cells)."""
        empty = [""] * n
        for cells in zip(*(_cells(rows[c], n) if c in rows else empty for c in self.columns)):
            self._row(list(cells))
        self._fh.flush()

    def digest(self) -> str:
        """SHA-256 of the header and every row written so far (see :func:`rows_digest`)."""
        return self._hash.copy().hexdigest()

    def close(self) -> None:
        self._fh.close()


def read_csv(path: str | Path) -> dict[str, np.ndarray]:
    """Columns of a CSV written here; numeric columns as float arrays (empty cells -> nan)."""
    with open(path, newline="", encoding="utf-8") as fh:
        rows = list(csv.reader(fh))
    header, body = rows[0], rows[1:]
    out: dict[str, np.ndarray] = {}
    for j, name in enumerate(header):
        col = [r[j] if j < len(r) else "" for r in body]
        try:
            out[name] = np.array([float(v) if v != "" else np.nan for v in col])
        except ValueError:
            out[name] = np.array(col)
    return out
