"""Reading input files and preparing output folders, with one clear line for every way they fail.

Every input file (case, law, material, path CSV, mesh) is read through :func:`read_text` or
checked by :func:`check_file`: a missing file, a folder, an unreadable or a non-UTF-8 file, or one
far too large to be an input, is a :class:`~rockfrac.errors.CaseError` naming the file, what is
wrong and what is expected. Output folders go through :func:`prepare_output`, which refuses to mix
two runs in one folder.
"""

from __future__ import annotations

import csv
import math
import os
import shutil
import tempfile
from collections.abc import Iterable
from pathlib import Path

from rockfrac.errors import CaseError

MAX_TEXT_BYTES = 64 * 2**20  # an input text file larger than this is not an input file


def check_file(path: str | Path, what: str) -> Path:
    """``path`` as a Path if it is a readable regular file; CaseError saying why not."""
    path = Path(path)
    try:
        st = path.stat()
    except FileNotFoundError:
        raise CaseError(f"{path}: no such file (expected {what})") from None
    except PermissionError:
        raise CaseError(f"{path}: cannot be read (permission denied); expected {what}") from None
    except OSError as err:
        raise CaseError(f"{path}: cannot be read ({err.strerror or err}); expected {what}") from None
    if path.is_dir():
        raise CaseError(f"{path}: is a folder, not a file (expected {what})")
    if not path.is_file():
        raise CaseError(f"{path}: is not a regular file (expected {what})")
    if not os.access(path, os.R_OK):
        raise CaseError(f"{path}: cannot be read (permission denied); expected {what}")
    if st.st_size > MAX_TEXT_BYTES and what.endswith("text)"):
        raise CaseError(f"{path}: {st.st_size / 2**20:.0f} MiB is too large for {what} "
                        f"(at most {MAX_TEXT_BYTES // 2**20} MiB)")
    return path


def read_bytes(path: str | Path, what: str) -> bytes:
    """The bytes of an input file; CaseError if it is missing, a folder or unreadable."""
    path = check_file(path, what)
    try:
        return path.read_bytes()
    except OSError as err:
        raise CaseError(f"{path}: cannot be read ({err.strerror or err}); expected {what}") from None


def read_text(path: str | Path, what: str) -> str:
    """The UTF-8 text of an input file (``what`` names what it should be, e.g. 'a case file (TOML
    text)'); CaseError if it is missing, a folder, unreadable, too large or not UTF-8."""
    data = read_bytes(path, what)
    if len(data) > MAX_TEXT_BYTES:
        raise CaseError(f"{path}: too large for {what} (at most {MAX_TEXT_BYTES // 2**20} MiB)")
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as err:
        raise CaseError(f"{path}: not UTF-8 text (invalid byte at offset {err.start}); expected {what}") from None
    if "\x00" in text:
        raise CaseError(f"{path}: holds NUL bytes, so it is binary, not text; expected {what}")
    return text


def read_table(path: str | Path, required: Iterable[str], what: str, max_abs: float = math.inf) -> dict[str, list[float]]:
    """The numeric columns of a CSV input (a header row, then one row per point), every cell a
    finite number of magnitude at most ``max_abs``; CaseError naming the file, the row (1-based,
    the header is row 1), the column and what is expected."""
    path = Path(path)
    required = list(required)
    expect = f"{what}: a header with columns {', '.join(required)}, then rows of finite numbers"
    text = read_text(path, f"{what} (CSV text)")
    try:
        rows = [(i + 1, r) for i, r in enumerate(csv.reader(text.splitlines())) if any(c.strip() for c in r)]
    except csv.Error as err:
        raise CaseError(f"{path}: not valid CSV ({err}); expected {expect}") from None
    if not rows:
        raise CaseError(f"{path}: empty; expected {expect}")
    _, header = rows[0]
    header = [h.strip() for h in header]
    twice = sorted({h for h in header if header.count(h) > 1})
    if twice:
        raise CaseError(f"{path}: column(s) {', '.join(twice)} given twice; expected {expect}")
    missing = [c for c in required if c not in header]
    if missing:
        raise CaseError(f"{path}: missing column(s) {', '.join(missing)}; expected {expect}")
    if len(rows) == 1:
        raise CaseError(f"{path}: no data rows after the header; expected {expect}")
    out: dict[str, list[float]] = {c: [] for c in header}
    for line, r in rows[1:]:
        if len(r) != len(header):
            raise CaseError(f"{path}: row {line} has {len(r)} cells, the header has {len(header)}; expected {expect}")
        for name, cell in zip(header, r):
            try:
                v = float(cell)
            except ValueError:
                raise CaseError(f"{path}: row {line}, column {name}: {cell.strip()!r} is not a number; "
                                f"expected {expect}") from None
            if not math.isfinite(v) or abs(v) > max_abs:
                raise CaseError(f"{path}: row {line}, column {name}: {cell.strip()} is not a finite number of "
                                f"magnitude at most {max_abs:g}; expected {expect}")
            out[name].append(v)
    return out


def _stale(out: Path, names: Iterable[str]) -> list[str]:
    return sorted(n for n in names if (out / n).exists() or (out / n).is_symlink())


def prepare_output(out: str | Path, outputs: Iterable[str], *, overwrite: bool = False,
                   resume: bool = False) -> Path:
    """Make ``out`` ready for a run's outputs (the file and folder names in ``outputs``).

    A fresh run into a folder that holds outputs of another run is refused unless ``overwrite``,
    which deletes those outputs (only those) first; ``resume`` keeps them (the caller checks that
    they belong together). CaseError if ``out`` is a file or cannot be created or written.
    """
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise CaseError(f"{out}: --out is a file, not a folder; give a folder for the run's outputs")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise CaseError(f"{out}: cannot create the output folder ({err.strerror or err})") from None
    try:
        with tempfile.TemporaryFile(dir=out):
            pass
    except OSError as err:
        raise CaseError(f"{out}: the output folder is not writable ({err.strerror or err})") from None
    names = list(outputs)
    stale = _stale(out, names)
    if resume or not stale:
        return out
    if not overwrite:
        raise CaseError(f"{out}: holds the outputs of another run ({', '.join(stale)}); use --overwrite to "
                        "replace them, --resume to continue that run, or another --out folder")
    for name in stale:
        target = out / name
        try:
            if target.is_dir() and not target.is_symlink():
                shutil.rmtree(target)
            else:
                target.unlink()
        except OSError as err:
            raise CaseError(f"{target}: cannot remove the old output ({err.strerror or err})") from None
    return out
