"""First-run and warm-run wall times of ``rockfrac paper``: what Numba's on-disk cache saves.

One command: ``.venv/bin/python benchmarks/startup.py``. Runs ``rockfrac paper`` three times in
fresh processes with ``NUMBA_CACHE_DIR`` pointing at an empty temporary folder: the first run
compiles every kernel and writes the cache, the next two load it. Also counts the kernels that
could not be cached (Numba warns "Cannot cache compiled function"). Writes
``results/startup.json`` and the table between the ``startup-table`` markers of README.md.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
from run import machine  # noqa: E402  (benchmarks/run.py: CPU, cores, library versions)

HERE = Path(__file__).parent
ROCKFRAC = Path(sys.executable).with_name("rockfrac")


def one_run(cache: Path, out: Path) -> dict:
    """Wall time of one ``rockfrac paper`` process and the kernels it could not cache."""
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache), PYTHONWARNINGS="default")
    t0 = time.perf_counter()
    proc = subprocess.run([str(ROCKFRAC), "paper", "--out", str(out)], env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        raise SystemExit(f"rockfrac paper failed:\n{proc.stdout[-2000:]}\n{proc.stderr[-2000:]}")
    uncached = sorted(set(re.findall(r'Cannot cache compiled function "(\w+)"', proc.stderr)))
    return {"wall_s": wall, "uncached": uncached}


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        cache = Path(tmp) / "numba"
        runs = [one_run(cache, Path(tmp) / f"out{k}") for k in range(3)]
        files = sum(1 for _ in cache.rglob("*.nbi"))
    info = machine()
    info["load_average"] = os.getloadavg()
    result = {"machine": info, "runs": runs, "cache_index_files": files}
    (HERE / "results").mkdir(exist_ok=True)
    (HERE / "results" / "startup.json").write_text(json.dumps(result, indent=1))
    first, warm = runs[0]["wall_s"], min(r["wall_s"] for r in runs[1:])
    lines = [
        f"Machine: {info['cpu']}, {info['cores']} cores; Numba {info['numba']}; {info['date']}; "
        f"load average before the table {info['load_average'][0]:.2f}.",
        "",
        "| run | wall time of `rockfrac paper` [s] |",
        "|---|---|",
        f"| first (empty Numba cache: every kernel compiled, {files} cache entries written) | {first:.1f} |",
        *(f"| warm {k} (kernels loaded from the cache) | {r['wall_s']:.1f} |" for k, r in enumerate(runs[1:], 1)),
        "",
        f"Compilation costs {first - warm:.1f} s of the first run; a warm run is {first / warm:.1f} x faster. "
        + (f"Kernels that could not be cached: {', '.join(runs[0]['uncached'])}."
           if runs[0]["uncached"] else "Every kernel was cached."),
    ]
    text = (HERE / "README.md").read_text()
    start, end = "<!-- startup-table:start -->", "<!-- startup-table:end -->"
    block = start + "\n" + "\n".join(lines) + "\n" + end
    text = re.sub(re.escape(start) + ".*?" + re.escape(end), block, text, flags=re.S) if start in text \
        else text.rstrip() + "\n\n## Numba cache: first and warm runs of `rockfrac paper`\n\n" + block + "\n"
    (HERE / "README.md").write_text(text)
    print("\n".join(lines))


if __name__ == "__main__":
    main()
