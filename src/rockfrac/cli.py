"""Command line: ``rockfrac run | drive | paper | penalty-study | compile | bifurcation``."""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np
from rich.console import Console
from rich.markup import escape

from rockfrac.bifurcation_cli import add_parser as add_bifurcation_parser
from rockfrac.errors import CaseError, RunStopped

console = Console(stderr=True, soft_wrap=True)


def _mpi_size() -> int:
    """The number of ranks this process was launched among (mpiexec's environment; 1 without it)."""
    for key in ("OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "MPI_LOCALNRANKS"):
        if os.environ.get(key, "").isdigit():
            return int(os.environ[key])
    return 1


def _distribution(size: int):
    """This rank's share of an MPI run (None on one process); on the ranks other than 0 the console
    is quiet (rank 0 reports)."""
    if size <= 1:
        return None
    try:
        from mpi4py import MPI

        from rockfrac.parallel.run import distribution
    except ImportError as err:
        raise CaseError(f"rockfrac run on {size} MPI ranks needs mpi4py and petsc4py ({err}); `make test` builds "
                        ".venv-mpi, a venv with Debian's python3-petsc4py-real and python3-mpi4py") from None
    if MPI.COMM_WORLD.Get_rank() > 0:
        console.quiet = True
    return distribution(MPI.COMM_WORLD)


def _cmd_run(args: argparse.Namespace) -> int:
    from rockfrac.case.schema import load_case
    from rockfrac.runner import run_case

    distribution = _distribution(_mpi_size())
    if args.resume and args.overwrite:
        raise CaseError("--resume and --overwrite contradict each other: resume continues the run in --out, "
                        "overwrite deletes it")
    case = load_case(args.case)

    def progress(row: dict) -> None:
        if args.quiet:
            return
        if "F_axial" in row:
            shown = f"u={row['u_axial']:.4e} m  F={row['F_axial']:10.2f} N/m"
        else:  # the largest reaction
            reactions = {k: v for k, v in row.items() if k.startswith("R_")}
            key = max(reactions, key=lambda k: abs(reactions[k]), default=None)
            shown = f"lf={row['load_factor']:.4f}" + (f"  {key}={reactions[key]:.4e}" if key else "")
        console.print(escape(f"step {row['step']:4d} {row['stage']:<11s} {shown}  it={row['newton_iterations']}"),
                      highlight=False)

    try:
        summary = run_case(case, args.out, progress=progress, path_label=str(args.case), resume=args.resume,
                           overwrite=args.overwrite,
                           on_start=lambda: console.print(f"[bold]rockfrac run[/] {escape(str(args.case))} -> "
                                                          f"{escape(str(args.out))}"),
                           warn=lambda w: console.print(f"[yellow]warning:[/] {escape(w)}", highlight=False),
                           distribution=distribution)
    except (CaseError, RunStopped):
        raise  # raised alike on every rank
    except BaseException as err:
        if distribution is None or os.environ.get("ROCKFRAC_DEBUG"):
            raise
        from mpi4py import MPI  # one rank failed: the others would wait for it in a collective call

        console.quiet = False
        _error(f"rank {distribution.rank}: {type(err).__name__}: {err}; ending every rank")
        MPI.COMM_WORLD.Abort(3)
        raise
    if summary.stop_signal is not None:
        console.print(f"[yellow]stopped by {summary.stop_signal}[/] after {summary.result.steps} steps; every "
                      f"converged step is in {escape(str(summary.out))}", highlight=False)
        return summary.exit_code
    style = "green" if summary.result.completed else "red"
    console.print(f"[{style}]{escape(summary.result.message)}[/] — {summary.result.steps} steps, "
                  f"{summary.newton_iterations} Newton iterations, {summary.wall_time:.2f} s; "
                  f"outputs in {escape(str(summary.out))}")
    return 0 if summary.result.completed else 1


def _read_path(path: Path) -> np.ndarray:
    """The jump path of ``rockfrac drive``: (n, 2) local jumps (t, n), or (n, 3) (t1, t2, n) of a 3D
    interface when the header names jump_t1, jump_t2 [m]."""
    from rockfrac.files import read_table, read_text
    from rockfrac.values import MAX_DISPLACEMENT

    first = next((line for line in read_text(path, "a jump path [m] (CSV text)").splitlines() if line.strip()), "")
    header = {h.strip() for h in first.split(",")}
    if header & {"jump_t1", "jump_t2"}:
        if "jump_t" in header:
            raise CaseError(f"{path}: columns jump_t (a 2D path) and jump_t1/jump_t2 (a 3D path) together; give "
                            "jump_t, jump_n or jump_t1, jump_t2, jump_n")
        names: tuple[str, ...] = ("jump_t1", "jump_t2", "jump_n")
    else:
        names = ("jump_t", "jump_n")
    cols = read_table(path, names, "a jump path [m]", max_abs=MAX_DISPLACEMENT)
    return np.column_stack([cols[c] for c in names])


def _cmd_drive(args: argparse.Namespace) -> int:
    from rockfrac.case.build import law_of_section
    from rockfrac.case.schema import load_law
    from rockfrac.files import prepare_output
    from rockfrac.output.csvout import CsvWriter

    law_file = load_law(args.law)
    jumps = _read_path(Path(args.path))
    out = prepare_output(args.out, ("drive.csv",), overwrite=True)  # a material-point run: replaced
    law = law_of_section(law_file.law)
    try:
        if jumps.shape[1] == 3:
            from rockfrac.laws.traction3d import drive_3d

            rows = drive_3d(law, jumps)
        else:
            rows = law.drive(jumps)
    except RuntimeError as err:
        raise CaseError(f"{args.path}: {err}") from None
    except ValueError as err:
        raise CaseError(f"{args.law}: [law]: {err}") from None
    w = CsvWriter(out / "drive.csv", list(rows))
    w.write_many(rows, len(rows["step"]))
    w.close()
    console.print(f"{len(rows['step'])} path points -> {out / 'drive.csv'}")
    return 0


def _cmd_paper(args: argparse.Namespace) -> int:
    from rich.progress import BarColumn, Progress, TaskID, TextColumn, TimeElapsedColumn

    from rockfrac.studies.paper import run_paper

    # refreshed by the rows themselves, at most 10 times a second: a refresher thread would keep
    # the study from forking its workers (rockfrac.studies.paper.fork_is_safe)
    with Progress(TextColumn("{task.description}"), BarColumn(), TextColumn("{task.fields[info]}"),
                  TimeElapsedColumn(), console=console, disable=args.quiet, auto_refresh=False) as bar:
        tasks: dict[str, TaskID] = {}
        shown = [0.0]

        def progress(name: str, row: dict) -> None:
            if name not in tasks:
                tasks[name] = bar.add_task(name, total=None, info="")
            bar.update(tasks[name], advance=1, info=f"step {row['step']} it {row['newton_iterations']} "
                       f"u={1e3 * row['u_axial']:.3f} mm F={row['F_axial']:.0f} N/m")
            if time.monotonic() - shown[0] > 0.1:
                shown[0] = time.monotonic()
                bar.refresh()

        jobs = args.jobs if args.jobs is not None else min(2, os.cpu_count() or 1)
        results = run_paper(args.out, args.steps, progress, jobs)
    for r in results:
        console.print(f"{r.name}: {'completed' if r.completed else escape(r.message)}, {r.iterations} iterations, "
                      f"{r.wall:.2f} s", highlight=False)
    console.print(f"report: {args.out / 'report.md'}")
    return 0 if all(r.completed for r in results) else 1


def _cmd_penalty(args: argparse.Namespace) -> int:
    from rockfrac.studies.penalty import run_penalty_study

    with console.status("penalty study: EP CSE k = 1e7 ... 1e12 Pa/m against RP") as status:
        rows = run_penalty_study(args.out, axial_steps=args.steps,
                                 progress=lambda k: status.update(f"penalty study: EP CSE k = {k:.0e} Pa/m"))
    for r in rows:
        console.print(f"k = {r.k:.0e} Pa/m: k L/E' = {r.k_l_over_e:.3g}, slope error {r.slope_error:.2e}, "
                      f"dissipation error {r.dissipation_error:.2e} {r.note}", highlight=False)
    console.print(f"report: {args.out / 'penalty.md'}")
    return 0


def _cmd_compile(args: argparse.Namespace) -> int:
    from rockfrac.precompile import LIST, compile_all

    jobs = args.jobs if args.jobs is not None else min(2, os.cpu_count() or 1)
    t0 = time.perf_counter()
    parts = compile_all(jobs)
    done = sum(p.done for p in parts)
    refused = [r for p in parts for r in p.refused]
    slowest = max((p.seconds for p in parts), default=0.0)
    console.print(f"compiled {done} kernel signatures of {LIST.name} on {len(parts)} processes in "
                  f"{time.perf_counter() - t0:.1f} s (the slowest {slowest:.1f} s) into the kernel cache",
                  highlight=False)
    for r in refused:
        console.print(f"[yellow]warning:[/] not compiled (it compiles at its first call): {escape(r)}",
                      highlight=False)
    return 0


def _whole_number(unit: str, low: int, high: int):
    """An argparse type: a whole number of ``unit`` from ``low`` to ``high``."""

    def parse(text: str) -> int:
        try:
            n = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a whole number of {unit}, got {text!r}") from None
        if not low <= n <= high:
            raise argparse.ArgumentTypeError(f"expected {low} to {high} {unit}, got {n}")
        return n

    return parse


_steps = _whole_number("steps", 1, 1_000_000)  # --steps
_jobs = _whole_number("processes", 1, 64)  # --jobs: cases at once


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="rockfrac", description="Quasi-static FE fracture of rock.")
    sub = p.add_subparsers(dest="command", required=True)
    r = sub.add_parser("run", help="run a case file")
    r.add_argument("case", type=Path)
    r.add_argument("--out", type=Path, required=True, help="output directory")
    r.add_argument("--quiet", action="store_true", help="no per-step progress lines")
    r.add_argument("--resume", action="store_true",
                   help="continue from the last checkpoint in --out ([output] checkpoint_every)")
    r.add_argument("--overwrite", action="store_true",
                   help="delete the outputs of an earlier run in --out first (without it such a folder is refused)")
    r.set_defaults(func=_cmd_run)
    d = sub.add_parser("drive", help="material-point driver of a traction law along a jump path")
    d.add_argument("law", type=Path, help="law file (TOML, [law] section)")
    d.add_argument("--path", type=Path, required=True,
                   help="CSV with columns jump_t, jump_n [m] (3D: jump_t1, jump_t2, jump_n)")
    d.add_argument("--out", type=Path, required=True)
    d.set_defaults(func=_cmd_drive)
    pp = sub.add_parser("paper", help="reproduce the paper's numerical study (figures, CSVs, report)")
    pp.add_argument("--out", type=Path, required=True)
    pp.add_argument("--steps", type=_steps, default=400, help="axial steps per case (default 400)")
    pp.add_argument("--quiet", action="store_true")
    pp.add_argument("--jobs", type=_jobs, default=None,
                    help="cases run at once, each in its own process (default: 2 where the machine has 2 cores or more)")
    pp.set_defaults(func=_cmd_paper)
    ps = sub.add_parser("penalty-study", help="EP CSE penalty stiffness against RP: errors vs k, rule of thumb")
    ps.add_argument("--out", type=Path, required=True)
    ps.add_argument("--steps", type=_steps, default=400, help="axial steps per case (default 400)")
    ps.set_defaults(func=_cmd_penalty)
    c = sub.add_parser("compile", help="compile the kernels for a first run, on several processes at once")
    c.add_argument("--jobs", type=_jobs, default=None,
                   help="processes compiling at once (default: 2 where the machine has 2 cores or more)")
    c.set_defaults(func=_cmd_compile)
    add_bifurcation_parser(sub)
    return p


def _error(text: str) -> None:
    console.print("[red]error:[/]", end=" ")
    console.print(text, markup=False, highlight=False)


def main(argv: list[str] | None = None) -> int:
    """Run a command; every failure is reported in a line or a few, never a traceback (set
    ROCKFRAC_DEBUG=1 to see one for an internal error). Exit codes: 0 done, 1 a run that stopped
    before its end (no convergence), 2 bad input, 3 an internal error, 130/143 stopped by
    SIGINT/SIGTERM (the converged steps kept)."""
    try:
        args = parser().parse_args(argv)
    except SystemExit as exit_:  # --help, or argparse's usage error (already printed)
        return int(exit_.code or 0)
    try:
        return args.func(args)
    except CaseError as err:
        _error(str(err))
        return 2
    except RunStopped as stop:
        console.print(f"[yellow]{escape(str(stop))}[/]", highlight=False)
        return stop.exit_code
    except KeyboardInterrupt:
        console.print("[yellow]interrupted (SIGINT)[/]", highlight=False)
        return 130
    except MemoryError:
        _error("out of memory: the problem is too large for this machine (fewer cells or steps, or a "
               "machine with more memory)")
        return 2
    except Exception as err:  # noqa: BLE001 (the last line of defence: no traceback reaches the user)
        if os.environ.get("ROCKFRAC_DEBUG"):
            raise
        _error(f"internal error ({type(err).__name__}: {err}); this is a bug in rockfrac: please report it "
               "with the command and input files (ROCKFRAC_DEBUG=1 shows the traceback)")
        return 3


if __name__ == "__main__":
    sys.exit(main())
