"""Observers of the stepping: each converged step is handed to every observer, which writes one
output (history.csv, points.csv, the ParaView series, run.log, checkpoints) or acts on it (stop
rules, progress). An observer sees the committed state only; none changes it.
"""

from __future__ import annotations

from abc import ABC
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rockfrac.model import Model
from rockfrac.output import checkpoint
from rockfrac.output.csvout import CsvWriter
from rockfrac.output.fragments import Pieces
from rockfrac.solve.stepping import Position, StepInfo, StopRun


@dataclass
class Step:
    """What the observers get: the stepping's record, the history row and the point records."""

    info: StepInfo
    row: dict
    points: dict[str, np.ndarray] | None


class Observer(ABC):
    """Receives every converged step; closes its files at the end (also after a failure)."""

    def step(self, step: Step) -> None:  # noqa: B027 (an observer may only close)
        """React to a converged step."""

    def close(self) -> None:  # noqa: B027
        """Release files (idempotent)."""


class HistoryCsv(Observer):
    def __init__(self, path: Path, columns: list[str], keep_steps: int | None):
        self.writer = CsvWriter(path, columns, keep_steps=keep_steps)

    def step(self, step: Step) -> None:
        self.writer.write(step.row)

    def digest(self) -> str:
        return self.writer.digest()

    def close(self) -> None:
        self.writer.close()


class PointsCsv(Observer):
    def __init__(self, path: Path, columns: list[str], keep_steps: int | None):
        self.writer = CsvWriter(path, columns, keep_steps=keep_steps)

    def step(self, step: Step) -> None:
        rec = step.points
        if rec is None:
            return
        n = rec["x"].shape[0]
        rec = dict(rec, step=np.full(n, step.info.step))
        self.writer.write_many(rec, n)

    def close(self) -> None:
        self.writer.close()


class FragmentsCsv(Observer):
    """fragments.csv: the pieces of the last converged step (fragment 0 the largest), each with its
    cells, size [m^2 in 2D, m^3 in 3D] and centroid [m]; written when the run ends."""

    def __init__(self, path: Path, pieces: Callable[[], Pieces | None]):
        self.path, self.pieces, self.last = path, pieces, 0

    def step(self, step: Step) -> None:
        self.last = step.info.step

    def close(self) -> None:
        p = self.pieces()
        if p is None:
            return
        rec = {"fragment": np.arange(p.count), "cells": p.cells, "size": p.size,
               **{"xyz"[a]: p.centroid[:, a] for a in range(p.centroid.shape[1])},
               "step": np.full(p.count, self.last)}
        writer = CsvWriter(self.path, list(rec))
        writer.write_many(rec, p.count)
        writer.close()


class VtkSeriesWriter(Observer):
    """The ParaView series: every ``every``-th step, its fields from ``fields(u)``.

    pieces: an MPI run's (rank, number of ranks, a barrier): each rank writes the piece
    ``fields(u)`` gives it and rank 0 the .pvtu joining them (rockfrac.output.vtk.VtkSeries)."""

    def __init__(self, folder: Path, every: int, fields: Callable, resume_at: int | None,
                 pieces: tuple[int, int, Callable[[], None]] | None = None):
        from rockfrac.output.vtk import VtkSeries

        rank, ranks = (pieces[0], pieces[1]) if pieces is not None else (0, 1)
        self.barrier = pieces[2] if pieces is not None else None
        self.series = VtkSeries(folder, resume=resume_at is not None, rank=rank, ranks=ranks)
        if resume_at is not None:
            self.series.truncate_after(resume_at)
        self.every, self.fields = every, fields

    def step(self, step: Step) -> None:
        if step.info.step % self.every == 0:
            fields = self.fields(step.info.u)
            if self.barrier is None:
                self.series.write(step.info.step, float(step.info.step), fields)
            else:
                self.series.write_piece(step.info.step, float(step.info.step), fields, self.barrier)


class Quiet(Observer):
    """The log of an MPI rank other than 0: it says nothing (rank 0 writes run.log)."""

    def __call__(self, line: str) -> None:
        pass


class RunLog(Observer):
    """run.log, line-buffered: one line per step, the Newton iterations, events, checkpoints."""

    def __init__(self, path: Path, resume_at: int | None, events: Callable[[], list[str]], pieces: int = 1):
        """pieces: the body's pieces at the start (a resumed run's, at its checkpoint)."""
        self.fh = _open_log(path, resume_at)
        self.events = events
        self.n_events = len(events()) if resume_at is not None else 0
        self.quantity = None  # the column the step line shows, besides the load factor
        self.pieces = pieces  # n_fragments of the last step logged

    def __call__(self, msg: str) -> None:
        if not self.fh.closed:
            self.fh.write(msg + "\n")

    def step(self, step: Step) -> None:
        info, row = step.info, step.row
        if "F_axial" in row:
            shown = f"u={row['u_axial']:.6e} F={row['F_axial']:.6e} "
        else:
            shown = ""
        self(f"step {info.step} [{info.stage}] lf={info.load_factor:.6f} {shown}iterations={info.newton.iterations}")
        lines = self.events()
        for line in lines[self.n_events:]:
            kind, _, text = line.partition(": ")
            self(f"  {kind} at step {info.step}: {text}")
        self.n_events = len(lines)
        if "n_fragments" in row:  # a mesh with cohesive surfaces
            pieces = int(row["n_fragments"])
            if pieces != self.pieces:
                self(f"  fragments at step {info.step}: the body is in {pieces} pieces (was {self.pieces}), "
                     f"separated = {row['separated']:.6g}")
            self.pieces = pieces

    def close(self) -> None:
        self.fh.close()


def _open_log(path: Path, resume_at: int | None):
    """run.log, line-buffered (a killed run's log is complete up to its last line). A resumed run's
    log is cut after the line of the checkpoint it resumes from, so no step appears twice."""
    if resume_at is None:
        return open(path, "w", buffering=1, encoding="utf-8")
    mark = f"  checkpoint at step {resume_at}"
    try:
        lines = path.read_text(encoding="utf-8").splitlines()
    except (OSError, UnicodeDecodeError):
        lines = []
    cut = max((i for i, line in enumerate(lines) if line == mark), default=None)
    fh = open(path, "w", buffering=1, encoding="utf-8")
    if cut is None:
        fh.write(f"(run.log of the earlier run did not record its checkpoint at step {resume_at}; "
                 "its lines were dropped)\n")
    else:
        fh.write("".join(line + "\n" for line in lines[: cut + 1]))
    return fh


def position_arrays(p: Position) -> dict[str, np.ndarray]:
    """A stepping position as plain arrays (for the checkpoint)."""
    out = {"stage": np.array(p.stage), "lam": np.array(p.lam), "u": p.u, "count": np.array(p.count),
           "stage_steps": np.array(p.stage_steps), "size_load": np.array(p.size.get("load", np.nan)),
           "size_path": np.array(p.size.get("path", np.nan)), "has_size": np.array(bool(p.size)),
           "forced": np.array(p.forced), "has_d_start": np.array(p.d_start is not None),
           "d_start": p.d_start if p.d_start is not None else np.zeros(0)}
    if p.f_int is not None:
        out["f_int"] = p.f_int
    if p.u_before is not None:
        out["u_before"] = p.u_before
    if p.path_nominal is not None:
        out["path_nominal"] = np.array(p.path_nominal)
    return out


def position_from_arrays(a: dict[str, np.ndarray]) -> Position:
    """The inverse of :func:`position_arrays` (KeyError if a field is missing)."""
    size = {"load": float(a["size_load"]), "path": float(a["size_path"])} if bool(a["has_size"]) else {}
    return Position(int(a["stage"]), float(a["lam"]), a["u"].astype(float), int(a["count"]), int(a["stage_steps"]),
                    size, bool(a["forced"]), a["d_start"].astype(float) if bool(a["has_d_start"]) else None,
                    a["f_int"].astype(float) if "f_int" in a else None,
                    a["u_before"].astype(float) if "u_before" in a else None,
                    float(a["path_nominal"]) if "path_nominal" in a else None)


class Checkpoints(Observer):
    """A checkpoint every ``every`` steps (0: never), with the hash of the history written so far.

    On a distributed ``model`` every rank writes its own file, nothing gathered: the position with its
    vectors (on its local dofs, owned and ghosts: all it holds) and its groups' state;
    rank 0's (``checkpoint.npz``) also has the run's counters and the hash of ``history`` (its CSV).
    """

    def __init__(self, folder: Path, every: int, model: Model, counters: Callable[[], dict[str, float]],
                 history: HistoryCsv | None, case_sha: str, log: Callable[[str], None], rank: int = 0):
        self.folder, self.every, self.model, self.counters = folder, every, model, counters
        self.history, self.case_sha, self.log, self.rank = history, case_sha, log, rank

    def step(self, step: Step) -> None:
        info = step.info
        if not self.every or info.step % self.every or info.position is None:
            return
        model, p = self.model, info.position
        states = [g.checkpoint_state() for g in model.groups]
        ranks = {"ranks": float(model.reduce_sum(1))} if model.distributed else {}
        arrays = position_arrays(p)
        if model.distributed:  # which dofs the vectors' entries are: resumed only on the same ones
            arrays["local_dofs_sha256"] = np.array(model.local_signature())
        if self.rank == 0:
            assert self.history is not None
            checkpoint.save(self.folder, arrays, states, {**self.counters(), **ranks}, self.case_sha,
                            self.history.digest())
        else:
            checkpoint.save(self.folder, arrays, states, ranks, self.case_sha, "", checkpoint.rank_file(self.rank))
        model.reduce_sum(0)  # every rank's file is in place before the log says so
        self.log(f"  checkpoint at step {info.step}")


class StopRules(Observer):
    """End the program once a quantity falls below a fraction of its peak magnitude (per stage rule);
    the peak runs over the steps of the stages that carry a rule on that quantity."""

    def __init__(self, stops: list, peaks: dict[str, float]):
        self.stops = stops
        self.peaks = peaks

    def step(self, step: Step) -> None:
        rule = self.stops[step.info.stage_index] if step.info.stage_index < len(self.stops) else None
        if rule is None:
            return
        value = abs(float(step.row[rule.quantity]))
        peak = self.peaks.get(rule.quantity, 0.0)
        self.peaks[rule.quantity] = peak = max(peak, value)
        if value < rule.below_peak_fraction * peak:
            raise StopRun(f"{rule.quantity} = {step.row[rule.quantity]:.6g} fell below {rule.below_peak_fraction} x "
                          f"its peak magnitude {peak:.6g}")


class Progress(Observer):
    def __init__(self, callback: Callable[[dict], None]):
        self.callback = callback

    def step(self, step: Step) -> None:
        self.callback(step.row)
