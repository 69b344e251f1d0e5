"""``rockfrac compile`` (rockfrac.precompile): the listed kernel signatures, read as data only; a run
recording what it compiled; the list compiled on two processes into a cache that a later process
loads without compiling."""

from __future__ import annotations

import inspect
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from numba.core import types

from rockfrac import precompile as pc


def test_the_list_names_kernels_with_their_number_of_arguments():
    """Every listed name is a kernel of the package and every signature has its parameters' count (a
    renamed kernel or a changed argument list fails here, not as a silent recompile); the heavy kernels
    of the first run are listed."""
    listed = pc.load()
    kernels = pc.dispatchers()
    assert sum(len(v) for v in listed.values()) > 50
    for name, sigs in listed.items():
        assert name in kernels, name
        n = len(inspect.signature(kernels[name].py_func).parameters)
        assert all(len(sig) == n for sig in sigs), name
    for heavy in ("rockfrac.elements.ede_kernel:ede_blocks__serial", "rockfrac.laws.mohr_coulomb_surface:ep_points__serial"):
        assert heavy in listed, heavy


@pytest.mark.parametrize("d", ["float64", "int32", "boolean", {"array": ["float64", 3, "C", False]},
                               {"array": ["int64", 1, "A", True]}, {"unituple": ["float64", 3]},
                               {"tuple": ["int64", {"array": ["float64", 2, "F", False]}]},
                               {"function": ["int64", ["float64", {"array": ["float64", 1, "C", False]}]]}])
def test_a_type_description_round_trips(d):
    assert pc.describe(pc.build(d)) == d


@pytest.mark.parametrize("d", ["__import__('os')", "object", {"array": ["float64", 99, "C", False]},
                               {"array": ["float64", 2, "X", False]}, {"array": ["str", 1, "C", False]},
                               {"module": "os"}, ["float64"], 3])
def test_anything_but_a_type_description_is_refused(d):
    with pytest.raises(ValueError):
        pc.build(d)


def test_types_the_format_does_not_describe_are_not_listed():
    with pytest.raises(pc.UnknownType):
        pc.describe(types.unicode_type)


def test_parts_keep_a_kernels_signatures_together_and_balance_the_count():
    """Each kernel, the most signatures first, goes to the part with the fewest so far; no part is empty."""
    listed = {"a:x": [[1]] * 5, "a:y": [[1]] * 3, "a:z": [[1]] * 2, "b:w": [[1]] * 2}
    split = pc.parts(listed, 2)
    assert [[name for name, _ in part] for part in split] == [["a:x", "b:w"], ["a:y", "a:z"]]
    assert [sum(len(s) for _, s in part) for part in split] == [7, 5]
    assert len(pc.parts(listed, 8)) == 4


RECORD = """
import numpy as np
from rockfrac.solve.backend import is_symmetric
print(is_symmetric(np.arange(4), np.arange(3), np.ones(3), 1e-13))
"""

LOAD = """
import numpy as np
from rockfrac.solve.backend import is_symmetric
print(is_symmetric(np.arange(4), np.arange(3), np.ones(3), 1e-13), sum(is_symmetric.stats.cache_hits.values()),
      sum(is_symmetric.stats.cache_misses.values()))
"""


def test_a_recorded_signature_compiled_on_two_processes_is_loaded_by_the_next(tmp_path):
    """A process run with ROCKFRAC_RECORD_KERNELS writes the signature it called; merged into a list
    with another kernel's, `compile_all` compiles the two on two processes into an empty cache, and a
    new process calling the kernel loads it (a cache hit, nothing compiled)."""
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    rec = tmp_path / "rec"
    subprocess.run([sys.executable, "-c", RECORD], env=dict(env, ROCKFRAC_RECORD_KERNELS=str(rec),
                                                            NUMBA_CACHE_DIR=str(tmp_path / "c0")),
                   check=True, capture_output=True, text=True)
    listed = tmp_path / "list.json"
    assert pc.merge(rec, listed) == 1
    got = json.loads(listed.read_text())
    assert got == {"rockfrac.solve.backend:is_symmetric": [[{"array": ["int64", 1, "C", False]}] * 2
                                                            + [{"array": ["float64", 1, "C", False]}, "float64"]]}
    got["rockfrac.model:serial_dot"] = [[{"array": ["float64", 1, "C", False]}] * 2]
    listed.write_text(json.dumps(got))
    cache = tmp_path / "cache"
    code = (f"import sys; from pathlib import Path; from rockfrac.precompile import compile_all; "
            f"parts = compile_all(2, Path({str(listed)!r})); "
            f"print(len(parts), sum(p.done for p in parts), sum(len(p.refused) for p in parts))")
    done = subprocess.run([sys.executable, "-c", code], env=dict(env, NUMBA_CACHE_DIR=str(cache)), check=True,
                          capture_output=True, text=True)
    assert done.stdout.split() == ["2", "2", "0"], done.stdout + done.stderr
    again = subprocess.run([sys.executable, "-c", LOAD], env=dict(env, NUMBA_CACHE_DIR=str(cache)), check=True,
                           capture_output=True, text=True)
    assert again.stdout.split() == ["True", "1", "0"]


def test_a_stale_signature_is_reported_not_compiled(tmp_path):
    listed = tmp_path / "list.json"
    listed.write_text(json.dumps({"rockfrac.solve.backend:is_symmetric": [["float64"]],
                                  "rockfrac.nowhere:kernel": [["float64"]]}))
    [part] = pc.compile_all(1, listed)
    assert part.done == 0 and len(part.refused) == 2
    assert "no such kernel" in part.refused[1] or "no such kernel" in part.refused[0]


def test_the_compile_command_refuses_a_bad_job_count(capsys):
    from rockfrac.cli import main

    assert main(["compile", "--jobs", "0"]) == 2
    assert "expected 1 to 64 processes" in capsys.readouterr().err
