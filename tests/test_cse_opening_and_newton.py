"""Pure opening against its closed form through the FE model, and Newton's convergence rate."""

import re

import numpy as np
import pytest
from conftest import paper_case, with_law

A = 1e3  # alpha_chi = alpha_c
OPENING_LAW = {"chi_p": 15680.0, "c_p": 20000.0, "chi_r": 0.0, "c_r": 0.0, "alpha_chi": A, "alpha_c": A}


def tension_case(form: str, steps: int, k: float | None = None) -> dict:
    """Two quads and a horizontal crack pulled apart (no confinement): pure mode I."""
    case = with_law(paper_case(form, k, confinement=0.0, axial_displacement=-3e-3, axial_steps=steps),
                    **OPENING_LAW)
    case["mesh"]["crack_angle"] = 0.0
    return case


def closed_form(u_p):
    """T_n = chi = chi_p / (1 + a chi_p [[u_n^p]] / G_f^I) (PAPER_NOTES, Sect. 4.2)."""
    return OPENING_LAW["chi_p"] / (1.0 + A * OPENING_LAW["chi_p"] * u_p / 1e4)


@pytest.mark.parametrize("form,k", [("rp", None), ("ep", 1e11)])
def test_fe_pure_opening_follows_the_closed_form(run, form, k):
    errors = []
    for steps in (300, 600):
        _, pts, s = run(tension_case(form, steps, k), f"{form}{steps}")
        assert s.result.completed
        plastic = pts["state"] == "plastic"
        assert plastic.sum() > 100
        assert np.abs(pts["T_t"]).max() < 1e-6 and np.abs(pts["jump_p_t"]).max() < 1e-15
        u_p = pts["jump_p_n"][plastic]
        assert u_p.max() > 2e-3  # chi has dropped to ~20% of its peak
        err = np.abs(pts["T_n"][plastic] - closed_form(u_p)).max() / OPENING_LAW["chi_p"]
        errors.append(err)
        np.testing.assert_allclose(pts["chi"][plastic], pts["T_n"][plastic], rtol=1e-9)
    assert errors[1] < 0.006
    assert 1.7 < errors[0] / errors[1] < 2.3  # backward Euler: first order in the step


@pytest.mark.parametrize("form,k", [("rp", None), ("ep", 1e11)])
def test_fe_pure_opening_trapezoidal_rule_is_second_order(run, form, k):
    """The same closed form with work_rule = 'trapezoidal': error / 4 per halved step. The activation
    is a step of its own (located), so the first plastic step of the RP form starts on the yield
    surface and takes the trapezoidal rule too (stepped over, its onset step is backward Euler, and
    that step's error, 2.2e-5 of chi_p, stays in the later states)."""
    errors = []
    for steps in (75, 150, 300):
        case = with_law(tension_case(form, steps, k), work_rule="trapezoidal")
        _, pts, s = run(case, f"{form}{steps}")
        assert s.result.completed
        plastic = pts["state"] == "plastic"
        u_p = pts["jump_p_n"][plastic]
        assert u_p.max() > 2e-3
        errors.append(np.abs(pts["T_n"][plastic] - closed_form(u_p)).max() / OPENING_LAW["chi_p"])
    errors = np.array(errors)
    assert errors.max() < 1.2e-4  # backward Euler at 600 steps: 6e-3 (above)
    ratios = errors[:-1] / errors[1:]
    assert np.all((ratios > 3.8) & (ratios < 4.2)), ratios


def iteration_residuals(log_text: str) -> dict[int, list[float]]:
    """Relative residuals per iteration of each converged step, from run.log."""
    steps: dict[int, list[float]] = {}
    for m in re.finditer(r"step (\d+) it (\d+): residual (\S+)", log_text):
        step, it, r = int(m.group(1)), int(m.group(2)), float(m.group(3))
        if it == 0:
            steps[step] = []
        steps[step].append(r)
    return steps


@pytest.mark.parametrize("rule", ["backward_euler", "trapezoidal"])
@pytest.mark.parametrize("form,k", [("rp", None), ("ep", 1e9)])
def test_plastic_steps_converge_quadratically(tmp_path, form, k, rule):
    from rockfrac.case.schema import parse_case
    from rockfrac.runner import run_case

    case = paper_case(form, k, axial_displacement=1.5e-3, axial_steps=15)  # big steps: many iterations
    case["cohesive"]["work_rule"] = rule
    # the activation inside a step (not located): the step that crosses it iterates most
    case["solver"] = {"tol_residual": 1e-13, "tol_energy": 1e-20, "locate_activation": False}
    run_case(parse_case(case), tmp_path)
    steps = iteration_residuals((tmp_path / "run.log").read_text())
    orders = []
    for res in steps.values():
        r = [x for x in res[1:] if x > 1e-13]  # 100 x above the round-off floor (~1e-15)
        for a, b, c in zip(r, r[1:], r[2:]):
            if b < 1e-2:  # in the asymptotic range
                orders.append(np.log(c / b) / np.log(b / a))
    assert len(orders) >= 3
    assert min(orders) > 1.4 and np.median(orders) > 1.8
