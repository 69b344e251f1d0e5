"""Command line: ``rockfrac run | drive | paper``."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
from rich.console import Console

from rockfrac.case.schema import CaseError

console = Console(stderr=True, soft_wrap=True)


def _cmd_run(args: argparse.Namespace) -> int:
    from rockfrac.case.schema import load_case
    from rockfrac.run import run_case

    from rockfrac.case.build import build
    from rockfrac.run import case_warnings

    case = load_case(args.case)
    console.print(f"[bold]rockfrac run[/] {args.case} -> {args.out}")
    for w in case_warnings(build(case, str(args.case))):
        console.print(f"[yellow]warning:[/] {w}", highlight=False)

    def progress(row: dict) -> None:
        if not args.quiet:
            console.print(
                f"step {row['step']:4d} {row['stage']:<11s} u={row['u_axial']:.4e} m  "
                f"F={row['F_axial']:10.2f} N/m  it={row['newton_iterations']}",
                highlight=False,
            )

    summary = run_case(case, args.out, progress=progress, path_label=str(args.case), resume=args.resume)
    style = "green" if summary.result.completed else "red"
    console.print(f"[{style}]{summary.result.message}[/] — {summary.result.steps} steps, "
                  f"{summary.newton_iterations} Newton iterations, {summary.wall_time:.2f} s; "
                  f"outputs in {summary.out}")
    return 0 if summary.result.completed else 1


def _read_path(path: Path) -> np.ndarray:
    from rockfrac.output.csvout import read_csv

    if not path.exists():
        raise CaseError(f"{path}: no such file")
    cols = read_csv(path)
    missing = [c for c in ("jump_t", "jump_n") if c not in cols]
    if missing:
        raise CaseError(f"{path}: missing column(s) {', '.join(missing)}; a path file has columns jump_t, jump_n [m]")
    jumps = np.column_stack([cols["jump_t"], cols["jump_n"]])
    if jumps.shape[0] == 0 or not np.all(np.isfinite(jumps)):
        raise CaseError(f"{path}: jump_t, jump_n must be numbers on every row (one row per path point)")
    return jumps


def _cmd_drive(args: argparse.Namespace) -> int:
    from rockfrac.case.build import law_of_section
    from rockfrac.case.schema import load_law
    from rockfrac.laws.drive import drive_path
    from rockfrac.output.csvout import CsvWriter

    law_file = load_law(args.law)
    jumps = _read_path(Path(args.path))
    try:
        rows = drive_path(law_of_section(law_file.law), jumps)
    except RuntimeError as err:
        raise CaseError(f"{args.path}: {err}") from None
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    cols = ["step", "jump_t", "jump_n", "T_t", "T_n", "jump_p_t", "jump_p_n", "eps_n_p", "eps_s_p",
            "chi", "c", "tan_phi", "tan_psi"]
    w = CsvWriter(out / "drive.csv", cols)
    w.write_many(rows, len(rows["step"]))
    w.close()
    console.print(f"{len(rows['step'])} path points -> {out / 'drive.csv'}")
    return 0


def _cmd_paper(args: argparse.Namespace) -> int:
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

    from rockfrac.studies.paper import run_paper

    with Progress(TextColumn("{task.description}"), BarColumn(), TextColumn("{task.fields[info]}"),
                  TimeElapsedColumn(), console=console, disable=args.quiet) as bar:
        tasks: dict[str, int] = {}

        def progress(name: str, row: dict) -> None:
            if name not in tasks:
                tasks[name] = bar.add_task(name, total=None, info="")
            bar.update(tasks[name], advance=1, info=f"step {row['step']} it {row['newton_iterations']} "
                       f"u={1e3 * row['u_axial']:.3f} mm F={row['F_axial']:.0f} N/m")

        results = run_paper(args.out, args.steps, progress)
    for r in results:
        console.print(f"{r.name}: {'completed' if r.completed else r.message}, {r.iterations} iterations, "
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


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="rockfrac", description="Quasi-static FE fracture of rock.")
    sub = p.add_subparsers(dest="command", required=True)
    r = sub.add_parser("run", help="run a case file")
    r.add_argument("case", type=Path)
    r.add_argument("--out", type=Path, required=True, help="output directory")
    r.add_argument("--quiet", action="store_true", help="no per-step progress lines")
    r.add_argument("--resume", action="store_true",
                   help="continue from the last checkpoint in --out ([output] checkpoint_every)")
    r.set_defaults(func=_cmd_run)
    d = sub.add_parser("drive", help="material-point driver of a traction law along a jump path")
    d.add_argument("law", type=Path, help="law file (TOML, [law] section)")
    d.add_argument("--path", type=Path, required=True, help="CSV with columns jump_t, jump_n [m]")
    d.add_argument("--out", type=Path, required=True)
    d.set_defaults(func=_cmd_drive)
    pp = sub.add_parser("paper", help="reproduce the paper's numerical study (figures, CSVs, report)")
    pp.add_argument("--out", type=Path, required=True)
    pp.add_argument("--steps", type=int, default=400, help="axial steps per case (default 400)")
    pp.add_argument("--quiet", action="store_true")
    pp.set_defaults(func=_cmd_paper)
    ps = sub.add_parser("penalty-study", help="EP CSE penalty stiffness against RP: errors vs k, rule of thumb")
    ps.add_argument("--out", type=Path, required=True)
    ps.add_argument("--steps", type=int, default=400, help="axial steps per case (default 400)")
    ps.set_defaults(func=_cmd_penalty)
    from rockfrac.bifurcation_cli import add_parser as _add_bif; _add_bif(sub)  # noqa: E702
    return p


def main(argv: list[str] | None = None) -> int:
    args = parser().parse_args(argv)
    try:
        return args.func(args)
    except CaseError as err:
        console.print("[red]error:[/]", end=" ")
        console.print(str(err), markup=False, highlight=False)
        return 2


if __name__ == "__main__":
    sys.exit(main())
