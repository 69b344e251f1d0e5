"""Cost per item of every item-parallel kernel on one thread, measured in real runs, against the cost
each kernel declares (``rockfrac.threads.parallel_kernel(cost=...)``, which sets its serial threshold).

One command: ``.venv/bin/python benchmarks/thread_rule.py`` (``--steps K`` limits each example's
steps, default 12; the band's 3 K, to reach its localization). Runs the examples below with every kernel forced onto its serial version
(``threads.FORCE = "serial"``, one thread), times every call, and reports per kernel the calls, the
item counts and the median time per item of the calls with at least 64 items (smaller calls are
dominated by the call overhead, which the rule does not need: it only asks where the work reaches
``SERIAL_WORK``). Writes ``results/thread_rule.json`` and the table between the
``thread-rule-table`` markers of README.md.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from collections import defaultdict
from pathlib import Path

HERE = Path(__file__).parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))
from run import machine, markdown_table, replace_table  # noqa: E402  (after the sys.path line)

EXAMPLES = {"examples/band/band.toml": 3, "examples/grains/grains.toml": 1,  # steps: x --steps
            "examples/rock_tests/brazilian/everywhere.toml": 1, "examples/rock_tests/borehole/breakout.toml": 1,
            "examples/rock_tests/brazilian/splitting.toml": 1}
MIN_ITEMS = 64


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--steps", type=int, default=12)
    args = ap.parse_args()
    from rockfrac import threads
    from rockfrac.case.build import build
    from rockfrac.case.schema import load_case
    from rockfrac.solve import linear
    from rockfrac.solve.newton import NewtonOptions
    from rockfrac.solve.stepping import SteppingOptions, run_stages

    calls: dict[str, list[tuple[int, float]]] = defaultdict(list)
    original = threads.ParallelKernel.__call__

    def timed(self, *a):
        t0 = time.perf_counter()
        out = original(self, *a)
        calls[self.__qualname__ + " (" + self.__module__.split(".")[-1] + ")"].append(
            (self.items(a), time.perf_counter() - t0))
        return out

    threads.ParallelKernel.__call__ = timed  # type: ignore[method-assign]
    threads.FORCE = "serial"
    for ex, times in EXAMPLES.items():
        case = load_case(ROOT / ex)
        built = build(case)
        stop = [0]

        def observe(info, stop=stop):
            stop[0] += 1
            if stop[0] >= args.steps * times:
                raise KeyboardInterrupt

        t0 = time.perf_counter()
        try:
            run_stages(built.model, built.stages, linear.make_solver("auto"), NewtonOptions(), SteppingOptions(),
                       observe)
        except KeyboardInterrupt:
            pass
        print(f"{ex}: {stop[0]} steps, {time.perf_counter() - t0:.1f} s", flush=True)
    by_name = {}
    declared = {k.__qualname__ + " (" + k.__module__.split(".")[-1] + ")": k for k in threads.KERNELS}
    for name, rows in sorted(calls.items()):
        big = [t / n for n, t in rows[1:] if n >= MIN_ITEMS]  # the first call may load the kernel
        big.sort()
        k = declared[name]
        by_name[name] = {"calls": len(rows), "items_max": max(n for n, _ in rows),
                         "measured_s_per_item": big[len(big) // 2] if big else None,
                         "declared_s_per_item": k.cost, "serial_below": k.below}
    info = machine()
    info["load_average"] = os.getloadavg()
    (HERE / "results").mkdir(exist_ok=True)
    (HERE / "results" / "thread_rule.json").write_text(json.dumps({"machine": info, "kernels": by_name}, indent=1))
    lines = [f"Machine: {info['cpu']}, {info['cores']} cores; Numba {info['numba']}; {info['date']}; load average "
             f"{info['load_average'][0]:.2f}; examples: {', '.join(Path(e).stem for e in EXAMPLES)}, "
             f"{args.steps} steps each (band: {3 * args.steps}).", "",
             ]
    rows = [[f"`{name}`", r["calls"], r["items_max"],
             "-" if r["measured_s_per_item"] is None else f"{1e6 * r['measured_s_per_item']:.3f}",
             f"{1e6 * r['declared_s_per_item']:.3f}", r["serial_below"]] for name, r in by_name.items()]
    lines += markdown_table(["kernel", "calls", "most items in a call", "measured [us/item]", "declared [us/item]",
                             "serial below [items]"], rows)
    print("\n".join(lines))
    replace_table("thread-rule-table", lines)


if __name__ == "__main__":
    main()
