"""Step growth after a cutback: judged on Newton's iterations without an active-set change.

With many cohesive points yielding, points switch (elastic or constrained <-> plastic) in most
iterations of a step whatever its size; counting those iterations against growth kept a cut-back
step small for the rest of a run (benchmarks/README.md, "Step growth")."""

import tomllib
from pathlib import Path

import numpy as np
import pytest

from rockfrac.case.build import build
from rockfrac.case.schema import parse_case
from rockfrac.elements.base import ElementGroup, Evaluation
from rockfrac.model import Model
from rockfrac.runner import engine_options
from rockfrac.solve import stepping
from rockfrac.solve.linear import make_solver
from rockfrac.solve.newton import Loads, NewtonOptions, newton_step
from rockfrac.solve.stepping import SteppingOptions, Stage, run_stages

ROOT = Path(__file__).resolve().parents[1]
K, H, X_YIELD = 100.0, 10.0, 0.01  # the spring's stiffnesses [N/m] and yield displacement [m]


class YieldingSpring(ElementGroup):
    """One spring on dof 0 (dof 1 linear): force k x up to x_y, then k x_y + h (x - x_y) [N]; it
    reports a switch where its branch differs from the previous iterate's (as a constraint would)."""

    def __init__(self):
        self.dofs = np.array([[0, 1]])
        self.plastic = False

    def evaluate(self, u, u_n):
        x = u[0]
        plastic = x > X_YIELD
        switched = int(plastic != self.plastic)
        self.plastic = plastic
        f = K * x if not plastic else K * X_YIELD + H * (x - X_YIELD)
        fe = np.array([[f, u[1]]])
        ke = np.array([[[H if plastic else K, 0.0], [0.0, 1.0]]])
        return Evaluation(fe, ke, n_switched=switched)


def spring_model() -> Model:
    return Model(1, [YieldingSpring()], np.zeros(0, dtype=np.int64), dim=2)


def test_newton_counts_the_iterations_that_switch_a_point():
    model = spring_model()
    zero = np.zeros(2)
    force = np.array([K * X_YIELD + H * 0.02, 0.0])  # past yield: x = x_y + 0.02
    res = newton_step(model, zero, 0.0, 1.0, Loads(np.zeros(0), np.zeros(0), zero, force),
                      make_solver("superlu"), NewtonOptions())
    assert res.converged and res.u[0] == pytest.approx(X_YIELD + 0.02, rel=1e-12)
    # it 0: elastic tangent; it 1: x = F / k is past yield (the switch); it 2: exact on the plastic branch
    assert res.switched == [0, 1, 0] and res.iterations == 2 and res.switching_iterations == 1
    lines: list[str] = []
    stepping._log_iterations(lines.append, "pull", 1, res)
    assert lines[1].endswith(", 1 point switched") and "switched" not in lines[0] + lines[2]


class ElasticPair(ElementGroup):
    """Two independent linear springs on dofs (0, 1), 1 N/m each."""

    def __init__(self):
        self.dofs = np.array([[0, 1]])

    def evaluate(self, u, u_n):
        return Evaluation(np.array([[u[0], u[1]]]), np.array([np.eye(2)]))


def grown_sizes(monkeypatch, switching: int) -> list[float]:
    """The load-factor increments of a linear spring pulled in 10 nominal steps, whose first step fails
    once and every converged step reports 10 Newton iterations, ``switching`` of them with a switch."""
    real = stepping.newton_step
    calls = {"n": 0}

    def hard_newton(*args, **kwargs):
        res = real(*args, **kwargs)
        calls["n"] += 1
        if calls["n"] == 1:
            res.converged = False  # a failed first attempt: the step is cut back
            res.message = "made to fail"
            return res
        res.iterations = 10
        res.switched = [0] + [2] * switching + [0] * (10 - switching)
        return res

    monkeypatch.setattr(stepping, "newton_step", hard_newton)
    model = Model(1, [ElasticPair()], np.zeros(0, dtype=np.int64), dim=2)
    stage = Stage("pull", steps=10, dirichlet_end=np.zeros(0), f_ext_end=np.array([1.0, 0.0]))
    lams = [0.0]
    result = run_stages(model, [stage], make_solver("superlu"), NewtonOptions(), SteppingOptions(),
                        lambda info: lams.append(info.load_factor))
    assert result.completed
    return np.diff(lams).tolist()


def test_a_cut_back_step_grows_back_when_its_hard_iterations_are_switches(monkeypatch):
    sizes = grown_sizes(monkeypatch, switching=6)  # 4 smooth iterations: easy
    assert sizes[:3] == pytest.approx([0.05, 0.075, 0.1])  # cut to half, then x 1.5 up to the nominal
    assert sizes[3:] == pytest.approx([0.1] * (len(sizes) - 4) + [sizes[-1]])
    assert sum(sizes) == pytest.approx(1.0)


def test_a_cut_back_step_with_many_smooth_iterations_stays_short(monkeypatch):
    sizes = grown_sizes(monkeypatch, switching=0)  # 10 smooth iterations: hard
    assert sizes == pytest.approx([0.05] * 20)


@pytest.mark.parametrize("example", ["cse_rp.toml", "cse_ep_k1e9.toml"])
def test_cohesive_points_report_their_switches(example):
    """RP points switch between constrained and plastic, EP points between elastic and plastic."""
    d = tomllib.loads((ROOT / "examples" / "paper" / example).read_text())
    d["output"] = {"vtk": False, "picture": False, "points": False}
    built = build(parse_case(d, example))
    group = built.cohesives[0]
    n = group.points.n
    u_n = built.model.initial_unknowns()
    opened = u_n.copy()
    normal = group.points.frame[:, 1, :]  # each point's unit normal (global frame)
    for a in range(2):  # the plus side pulled 1 mm along the normal: trials far outside the surface
        opened[2 * group.points.plus + a] = 1e-3 * normal[:, a]
    assert group.evaluate(u_n, u_n).n_switched == 0  # as committed
    assert group.evaluate(opened, u_n).n_switched == n  # every point turns plastic
    assert group.evaluate(opened, u_n).n_switched == 0  # the same iterate again
    assert group.evaluate(u_n, u_n).n_switched == n  # and back


def test_the_growth_is_set_in_the_solver_section():
    d = tomllib.loads((ROOT / "examples" / "paper" / "cse_rp.toml").read_text())
    d["output"] = {"vtk": False, "picture": False, "points": False}
    _, default = engine_options(build(parse_case(d, "rp.toml")))
    assert (default.grow, default.easy_iterations) == (1.5, 6)
    d["solver"] = {"grow": 1.2, "easy_iterations": 16}
    _, chosen = engine_options(build(parse_case(d, "rp.toml")))
    assert (chosen.grow, chosen.easy_iterations) == (1.2, 16)
