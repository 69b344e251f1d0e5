"""Row-by-row CSV writers that flush each step, so a stopped run keeps every converged step."""

from __future__ import annotations

import csv
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


def _fmt(v: Any) -> str:
    if v is None:
        return ""
    if isinstance(v, (float, np.floating)):
        return "" if np.isnan(v) else repr(float(v))
    return str(v)


class CsvWriter:
    """A CSV file with a fixed header; ``write`` appends rows and flushes."""

    def __init__(self, path: Path, columns: list[str], keep_steps: int | None = None):
        """A new file, or (keep_steps) the existing one cut to its rows with step <= keep_steps and
        appended to (a resumed run)."""
        self.columns = columns
        if keep_steps is not None and Path(path).exists():
            with open(path, newline="") as fh:
                rows = list(csv.reader(fh))
            step = rows[0].index("step")
            kept = [r for r in rows[1:] if r and int(float(r[step])) <= keep_steps]
            self._fh = open(path, "w", newline="")
            self._csv = csv.writer(self._fh)
            self._csv.writerow(rows[0])
            self._csv.writerows(kept)
        else:
            self._fh = open(path, "w", newline="")
            self._csv = csv.writer(self._fh)
            self._csv.writerow(columns)
        self._fh.flush()

    def write(self, row: dict[str, Any]) -> None:
        self._csv.writerow([_fmt(row.get(c)) for c in self.columns])
        self._fh.flush()

    def write_many(self, rows: dict[str, np.ndarray], n: int) -> None:
        for i in range(n):
            self._csv.writerow([_fmt(rows[c][i]) if c in rows else "" for c in self.columns])
        self._fh.flush()

    def close(self) -> None:
        self._fh.close()


def read_csv(path: str | Path) -> dict[str, np.ndarray]:
    """Columns of a CSV written here; numeric columns as float arrays (empty cells -> nan)."""
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    header, body = rows[0], rows[1:]
    out: dict[str, np.ndarray] = {}
    for j, name in enumerate(header):
        col = [r[j] for r in body]
        try:
            out[name] = np.array([float(v) if v != "" else np.nan for v in col])
        except ValueError:
            out[name] = np.array(col)
    return out
