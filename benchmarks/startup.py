"""First-run and warm-run wall times of ``rockfrac paper``: compiling, the Numba cache, threads.

One command: ``.venv/bin/python benchmarks/startup.py`` (``--no-busy`` skips the runs beside a busy
process). Every run is a fresh ``rockfrac paper`` process with ``NUMBA_CACHE_DIR`` pointing at a
temporary folder that starts empty:

1. *first*: an empty cache, every kernel a run needs is compiled and written. The time spent
   inside Numba's compiler is measured by its own event stream (``numba:compile``, the outermost
   events only, so a kernel compiled inside another is not counted twice): *compiling* below.
2. *warm* x 2: the kernels loaded from the cache.
3. *warm, NUMBA_NUM_THREADS=1*: the same, Numba on one thread.
4. beside a busy process (a pure-Python loop on one of the two cores): warm, and warm with one
   Numba thread, interleaved twice. The thread rule (rockfrac.threads) should make the two alike.

Also counts the kernels that could not be cached (Numba warns "Cannot cache compiled function").
Writes ``results/startup.json`` and the table between the ``startup-table`` markers of README.md.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
from run import machine, replace_table

HERE = Path(__file__).parent
PY = Path(sys.executable)

# rockfrac paper, with the outermost numba:compile events timed and printed to stderr at the end
WRAPPER = """if True:
    import sys, time
    from numba.core import event
    depth, total, start = [0], [0.0], [0.0]
    class Compile(event.Listener):
        def on_start(self, ev):
            if depth[0] == 0:
                start[0] = time.perf_counter()
            depth[0] += 1
        def on_end(self, ev):
            depth[0] -= 1
            if depth[0] == 0:
                total[0] += time.perf_counter() - start[0]
    event.register("numba:compile", Compile())
    import os
    from rockfrac.studies import paper
    worker = paper._worker
    def counted(*args):  # a forked worker inherits the listener: it writes its own total when it ends
        try:
            worker(*args)
        finally:
            with open(os.path.join(sys.argv[3], f"worker{os.getpid()}"), "w") as fh:
                fh.write(f"{total[0]:.3f}")
    paper._worker = counted
    from rockfrac.cli import main
    code = main(["paper", "--out", sys.argv[1], "--quiet", "--jobs", sys.argv[2]])
    print(f"COMPILE_SECONDS {total[0]:.3f}", file=sys.stderr)
    sys.exit(code)
"""


def one_run(cache: Path, out: Path, threads: int | None = None, jobs: int = 1) -> dict:
    """Wall time of one ``rockfrac paper`` process, its seconds in Numba's compiler, uncached kernels."""
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache), PYTHONWARNINGS="default")
    if threads is not None:
        env["NUMBA_NUM_THREADS"] = str(threads)
    load = os.getloadavg()[0]
    with tempfile.TemporaryDirectory() as counts:
        t0 = time.perf_counter()
        proc = subprocess.run([str(PY), "-c", WRAPPER, str(out), str(jobs), counts], env=env, capture_output=True,
                              text=True)
        wall = time.perf_counter() - t0
        workers = [float(f.read_text()) for f in Path(counts).glob("worker*")]
    if proc.returncode != 0:
        raise SystemExit(f"rockfrac paper failed:\n{proc.stdout[-2000:]}\n{proc.stderr[-2000:]}")
    uncached = sorted(set(re.findall(r'Cannot cache compiled function "(\w+)"', proc.stderr)))
    compiling = float(re.findall(r"COMPILE_SECONDS ([0-9.]+)", proc.stderr)[-1])
    if jobs > 1 and len(workers) != jobs:
        raise SystemExit(f"expected {jobs} forked workers to report their compiling, got {len(workers)}")
    return {"wall_s": wall, "compile_s": compiling if jobs == 1 else max(workers),
            "compile_sum_s": compiling + sum(workers), "uncached": uncached, "threads": threads, "jobs": jobs,
            "load": load}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--no-busy", action="store_true")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        cache = Path(tmp) / "numba"
        out = Path(tmp) / "out"
        runs = {"first, one process": one_run(cache, out)}
        files = sum(1 for _ in cache.rglob("*.nbi"))
        runs["warm 1, one process"] = one_run(cache, out)
        runs["warm 2, one process"] = one_run(cache, out)
        runs["warm, one process, 1 Numba thread"] = one_run(cache, out, threads=1)
        cache2 = Path(tmp) / "numba2"
        runs["first, two processes (the default here)"] = one_run(cache2, out, jobs=2)
        runs["warm 1, two processes"] = one_run(cache2, out, jobs=2)
        runs["warm 2, two processes"] = one_run(cache2, out, jobs=2)
        if not args.no_busy:
            busy = subprocess.Popen([str(PY), "-c", "while True: pass"])
            try:
                time.sleep(2.0)
                for k in (1, 2):
                    runs[f"warm, one process, busy process beside ({k})"] = one_run(cache, out)
                    runs[f"warm, one process, 1 Numba thread, busy process beside ({k})"] = one_run(cache, out,
                                                                                                   threads=1)
                runs["warm, two processes, busy process beside"] = one_run(cache2, out, jobs=2)
            finally:
                busy.kill()
    info = machine()
    info["load_average"] = os.getloadavg()
    result = {"machine": info, "runs": runs, "cache_index_files": files}
    (HERE / "results").mkdir(exist_ok=True)
    (HERE / "results" / "startup.json").write_text(json.dumps(result, indent=1))
    first = runs["first, one process"]
    warm = min(runs["warm 1, one process"]["wall_s"], runs["warm 2, one process"]["wall_s"])
    two_first = runs["first, two processes (the default here)"]
    warm2 = min(runs["warm 1, two processes"]["wall_s"], runs["warm 2, two processes"]["wall_s"])
    fmt = lambda v: "-" if v is None else f"{v:.1f}"
    lines = [
        f"Machine: {info['cpu']}, {info['cores']} cores; Numba {info['numba']}; {info['date']}.",
        "",
        "| run of `rockfrac paper` | wall time [s] | in Numba's compiler [s]: the slowest process (all) | "
        "load average before |",
        "|---|---|---|---|",
        *(f"| {name} | {r['wall_s']:.1f} | {fmt(r['compile_s'])} ({fmt(r['compile_sum_s'])}) | {r['load']:.2f} |"
          for name, r in runs.items()),
        "",
        f"The first run (empty cache, {files} cache entries written) spends {first['compile_s']:.1f} s in Numba's "
        f"compiler in one process; on two (forked) worker processes the slowest compiles for "
        f"{two_first['compile_s']:.1f} s and the run takes {two_first['wall_s']:.1f} s. A warm run takes "
        f"{warm:.1f} s in one process, {warm2:.1f} s on two. "
        + (f"Kernels that could not be cached: {', '.join(first['uncached'])}."
           if first["uncached"] else "Every kernel was cached."),
    ]
    busy_rows = [(runs[f"warm, one process, busy process beside ({k})"]["wall_s"],
                  runs[f"warm, one process, 1 Numba thread, busy process beside ({k})"]["wall_s"]) for k in (1, 2)
                 if f"warm, one process, busy process beside ({k})" in runs]
    if busy_rows:
        lines.append("Beside a busy process, one process with Numba's default threads / with one Numba thread: "
                     + ", ".join(f"{a / b:.2f}" for a, b in busy_rows) + ".")
    replace_table("startup-table", lines)
    print("\n".join(lines))


if __name__ == "__main__":
    main()
