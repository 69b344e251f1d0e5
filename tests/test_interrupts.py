"""A run killed or interrupted mid-way: valid outputs, a complete log, a bit-for-bit resume.

The runs are real processes of the command line, stopped by real signals while they step.
"""

from __future__ import annotations

import csv
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from rockfrac.cli import main
from rockfrac.output.csvout import read_csv

STEPS = 1000  # ~2 ms each: the run is still stepping when the signal comes (after 30 to 80 rows)
CASE = f"""
title = "RP CSE, many small steps"
[mesh]
crack_angle = 0.9989762274499867
[bulk]
E = 1.5e7
nu = 0.3
[cohesive]
form = "rp"
GfI = 1e4
GfII = 1e4
chi_p = 15680.0
chi_r = 0.0
c_p = 9053.0
c_r = 0.0
phi_p = 0.5236
phi_r = 0.0
psi_p = 0.087
alpha_chi = 2e3
alpha_c = 2e3
alpha_phi = 9e2
alpha_psi = 9e2
[loading]
confinement = 2e4
axial_displacement = 2e-3
axial_steps = {STEPS}
[output]
checkpoint_every = 25
picture = false
"""


@pytest.fixture(scope="module")
def case_and_reference(tmp_path_factory):
    folder = tmp_path_factory.mktemp("interrupts")
    case = folder / "case.toml"
    case.write_text(CASE)
    assert main(["run", str(case), "--out", str(folder / "full"), "--quiet"]) == 0
    return case, folder / "full"


def start_run(case: Path, out: Path) -> subprocess.Popen:
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    return subprocess.Popen([sys.executable, "-m", "rockfrac.cli", "run", str(case), "--out", str(out), "--quiet"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)


def wait_for_rows(proc: subprocess.Popen, history: Path, rows: int, timeout: float = 120.0) -> None:
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout:
        if proc.poll() is not None:
            pytest.fail(f"the run ended before it could be stopped: {proc.stderr.read()}")
        if history.exists() and history.read_text().count("\n") > rows:
            return
        time.sleep(0.005)
    proc.kill()
    pytest.fail("the run did not reach the rows in time")


def valid_csv(path: Path) -> list[list[str]]:
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    assert all(len(r) == len(rows[0]) for r in rows), f"{path}: a ragged row"
    return rows


def step_lines(log: str) -> list[int]:
    return [int(line.split()[1]) for line in log.splitlines() if line.startswith("step ")]


def test_resume_after_sigkill_is_bit_for_bit(case_and_reference, tmp_path):
    case, full = case_and_reference
    out = tmp_path / "cut"
    proc = start_run(case, out)
    wait_for_rows(proc, out / "history.csv", 80)
    proc.send_signal(signal.SIGKILL)
    proc.wait(timeout=30)
    assert proc.returncode == -signal.SIGKILL
    killed_log = (out / "run.log").read_text()
    assert step_lines(killed_log) == list(range(1, len(step_lines(killed_log)) + 1))  # complete up to the kill
    assert main(["run", str(case), "--out", str(out), "--resume", "--quiet"]) == 0
    for name in ("history.csv", "points.csv"):
        a, b = read_csv(full / name), read_csv(out / name)
        assert a.keys() == b.keys() and len(a["step"]) == len(b["step"])
        for k in a:
            if a[k].dtype.kind == "f":
                np.testing.assert_array_equal(a[k], b[k])  # bit for bit
            else:
                assert list(a[k]) == list(b[k])
    log = (out / "run.log").read_text()
    # one confinement step, the axial steps and the step that ends at the activation: no gap, none twice
    assert step_lines(log) == list(range(1, STEPS + 3))
    assert log.count("resumed from the checkpoint at step") == 1


def test_sigint_stops_cleanly_with_exit_130(case_and_reference, tmp_path):
    case, full = case_and_reference
    out = tmp_path / "int"
    proc = start_run(case, out)
    wait_for_rows(proc, out / "history.csv", 60)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    assert "Traceback" not in err and "stopped by SIGINT" in err
    log = (out / "run.log").read_text().splitlines()
    assert log[-1].startswith("end: stopped by SIGINT (Ctrl-C) after ")
    n = int(log[-1].split(" after ")[1].split()[0])
    history = valid_csv(out / "history.csv")
    assert [int(r[0]) for r in history[1:]] == list(range(1, n + 1))  # every converged step, nothing half
    points = valid_csv(out / "points.csv")
    assert {int(r[0]) for r in points[1:]} == set(range(1, n + 1))
    ref = read_csv(full / "history.csv")
    got = read_csv(out / "history.csv")
    np.testing.assert_array_equal(got["F_axial"], ref["F_axial"][:n])  # the same steps as the full run
    assert main(["run", str(case), "--out", str(out), "--resume", "--quiet"]) == 0  # and it goes on


def test_sigterm_stops_cleanly_with_exit_143(case_and_reference, tmp_path):
    case, _ = case_and_reference
    out = tmp_path / "term"
    proc = start_run(case, out)
    wait_for_rows(proc, out / "history.csv", 30)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 143, err
    assert "Traceback" not in err
    assert (out / "run.log").read_text().splitlines()[-1].startswith("end: stopped by SIGTERM after ")
