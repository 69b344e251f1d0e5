"""Newton stops as soon as its iterates cycle through two to four states (they would go round to the
iteration limit), and converges as before where they do not."""

import numpy as np
import pytest

from rockfrac.elements.base import ElementGroup, Evaluation
from rockfrac.model import Model
from rockfrac.solve.linear import make_solver
from rockfrac.solve.newton import CYCLE_TOL, Loads, NewtonOptions, _cycle_period, _cycling, newton_step


class Cubic(ElementGroup):
    """One element on dofs (0, 1): internal forces (x^3 - 2 x + 2, y) [N], whose Newton iteration
    from x = 0 alternates 0, 1, 0, 1... (the textbook 2-cycle); y is linear."""

    def __init__(self):
        self.dofs = np.array([[0, 1]])

    def evaluate(self, u, u_n):
        x, y = u[0], u[1]
        fe = np.array([[x**3 - 2.0 * x + 2.0, y]])
        ke = np.array([[[3.0 * x**2 - 2.0, 0.0], [0.0, 1.0]]])
        return Evaluation(fe, ke)


class SwitchingCubic(Cubic):
    """The same, reporting two points switched at every evaluation (an active set that never settles)."""

    def evaluate(self, u, u_n):
        ev = super().evaluate(u, u_n)
        return Evaluation(ev.fe, ev.ke, n_switched=2)


def solve(line_search: int, x0: float = 0.0, group=Cubic):
    model = Model(1, [group()], np.zeros(0, dtype=np.int64), dim=2)
    zero = np.zeros(2)
    loads = Loads(np.zeros(0), np.zeros(0), zero, zero)
    u0 = np.array([x0, 0.0])
    options = NewtonOptions(max_iterations=25, line_search=line_search)
    return newton_step(model, u0, 0.0, 1.0, loads, make_solver("superlu"), options)


def test_a_two_cycle_is_stopped_after_two_periods():
    res = solve(line_search=0)
    assert not res.converged
    assert res.residuals == pytest.approx([2.0, 1.0, 2.0, 1.0, 2.0])  # x = 0, 1, 0, 1, 0
    assert "cycle between two states" in res.message and res.message.startswith("iteration 4:")


def test_newton_that_does_not_cycle_converges_as_before():
    root = -1.7692923542386314  # the real root of x^3 - 2 x + 2
    res = solve(line_search=3)  # the line search breaks the cycle; the iterates wander, not periodic
    assert not res.converged and res.iterations == 25 and "no convergence in 25" in res.message
    res = solve(line_search=0, x0=-2.0)  # quadratic from nearby: no cycle on the way
    assert res.converged and res.u[0] == pytest.approx(root, rel=1e-12)
    assert "cycle" not in res.message


def test_the_cycle_test():
    assert _cycling([3.0, 1e-3, 8.8e-5, 1e-3, 8.8e-5, 1e-3, 8.8e-5])
    assert not _cycling([1e-3, 8.8e-5, 1e-3, 8.8e-5])  # one period is not yet two
    assert not _cycling([1e-3, 9e-5, 1e-3, 8.8e-5, 1e-3])  # still moving
    assert not _cycling([1e-3, 1e-3, 1e-3, 1e-3, 1e-3])  # a stall, not a 2-cycle
    assert not _cycling([0.0, 0.0, 0.0, 0.0, 0.0])


def test_cycles_of_three_and_four_states():
    """The grains' RP steps went round 3 iterates (3.818e-4, 2.630e-4, 7.167e-7) to the iteration limit:
    a period of 3 or 4 is recognised after two periods and one more, to CYCLE_TOL, shortest first."""
    three = [3.818e-4, 2.630e-4, 7.167e-7]
    assert _cycle_period([5.0, 1.0] + three * 2 + three[:1]) == 3
    assert _cycle_period(three * 2) == 0  # two periods are not yet enough
    assert _cycle_period([1.0] + [v * (1 + 0.1 * CYCLE_TOL) for v in three] + three + three[:1]) == 3  # round-off
    assert _cycle_period([v * (1 + 10 * CYCLE_TOL) for v in three] + three + three[:1]) == 0  # still moving
    four = [1e-2, 3e-4, 2e-3, 5e-7]
    assert _cycle_period(four * 2 + four[:1]) == 4
    assert _cycle_period([1e-3, 8.8e-5] * 4 + [1e-3]) == 2  # a 2-cycle is also a 4-cycle: the shorter is named
    assert _cycle_period([1e-3] * 9) == 0  # a stall


def test_a_failure_says_when_the_active_set_does_not_settle():
    for line_search in (0, 3):  # a cycle, and no convergence in 25 iterations
        plain, switching = solve(line_search), solve(line_search, group=SwitchingCubic)
        assert not plain.converged and not switching.converged
        assert "active set" not in plain.message
        window = 4 if line_search == 0 else 8  # the cycle stops at iteration 4
        assert switching.message == plain.message + (
            f"; points switched in {window} of the last {window} iterations (2 at a time): the active set "
            "does not settle")


def test_the_unsettled_note_counts_most_of_the_last_iterations():
    from rockfrac.solve.newton import unsettled

    chatter = [0, 3, 2] + [1, 1, 0, 1, 0, 1, 1, 0]  # it 0 (not counted), then a point flipping
    assert unsettled(chatter) == ("; points switched in 5 of the last 8 iterations (1 at a time): the active "
                                  "set does not settle")
    assert unsettled([0, 5, 0, 0, 1, 0, 0, 0, 0]) == ""  # settled
    assert unsettled([0, 1, 1, 1]) == ""  # too few iterations to say


class YieldKink(ElementGroup):
    """One dof x on a yield surface's kink (what an RP point sitting on its surface does to Newton):
    constrained for x < 1/2, internal force 1e-10 (1 - x) [N], an equilibrium within the tolerance
    at x = 0 whose nearly flat tangent sends the correction to x = 1; plastic for x >= 1/2, force
    4e-7 x, whose correction comes back to x = 0. Each change of branch counts as a switch."""

    def __init__(self):
        self.dofs = np.array([[0, 1]])
        self.mode = 1  # the step starts plastic, at x = 1

    def evaluate(self, u, u_n):
        x, y = u[0], u[1]
        mode = int(x >= 0.5)
        switched, self.mode = int(mode != self.mode), mode
        f, k = (4e-7 * x, 4e-7) if mode else (1e-10 * (1.0 - x), -1e-10)
        return Evaluation(np.array([[f, y]]), np.array([[[k, 0.0], [0.0, 1.0]]]), n_switched=switched)


def test_an_equilibrium_the_iteration_comes_back_to_by_switching_converges():
    # x = 0 is within the residual tolerance, but the energy norm weighs it by the switching
    # correction from x = 1 and never settles; once the iteration leaves it by switching and comes
    # back to it by switching, it converges there (it used to alternate until the cycle test stopped it)
    res = solve(line_search=0, x0=1.0, group=YieldKink)
    assert res.converged and res.iterations == 3 and res.u[0] == 0.0
    assert res.residuals == pytest.approx([4e-7, 1e-10, 4e-7, 1e-10])  # x = 1, 0, 1, 0
    assert res.switched == [0, 1, 1, 1]
    assert res.energies[-1] > 1e-5  # the energy norm alone would not have converged


def test_the_return_test():
    from rockfrac.solve.newton import _returned

    tol = 1e-8
    assert _returned([3e-5, 1e-10, 4e-7, 2e-10], [0, 5, 0, 4], tol)
    assert not _returned([3e-5, 1e-10, 4e-7, 2e-10], [0, 5, 0, 0], tol)  # came back without a switch
    assert not _returned([3e-5, 1e-10, 4e-7, 2e-10], [0, 0, 0, 4], tol)  # the first one came by iterating
    assert not _returned([3e-5, 2e-8, 4e-7, 2e-10], [0, 5, 0, 4], tol)  # the first one was not within tol
    assert not _returned([3e-5, 1e-10, 4e-9, 2e-10], [0, 5, 0, 4], tol)  # it never left the tolerance
    assert not _returned([1e-10, 4e-7, 2e-10], [5, 0, 4], tol)  # the step's start is not a return


class Scripted(ElementGroup):
    """One dof whose internal force at the k-th evaluation is forces[k] (tangent 1), reporting
    switches[k] points switched: a script of an iteration whose active set does or does not settle."""

    def __init__(self, forces, switches):
        self.dofs = np.array([[0, 1]])
        self.forces, self.switches, self.k = forces, switches, 0

    def evaluate(self, u, u_n):
        k = min(self.k, len(self.forces) - 1)
        self.k += 1
        return Evaluation(np.array([[self.forces[k], u[1]]]), np.array([[[1.0, 0.0], [0.0, 1.0]]]),
                          n_switched=self.switches[k])


def test_an_equilibrium_within_tolerance_converges_once_the_active_set_does_not_settle():
    """The iterate at 3e-9 (tolerance 1e-8) switched points, and its energy norm (weighed by the
    correction from 0.2) is 6e-10, above 1e-10. After points switched in every iteration before it,
    it converges there; where the iterations before it did not switch, it does not (the energy norm
    keeps the iteration going, and the script's next force, 0.3, is not an equilibrium)."""
    forces = [1.0, 0.5, 0.3, 0.2, 3e-9, 0.3]

    def run(switches):
        group = Scripted(forces, switches)
        model = Model(1, [group], np.zeros(0, dtype=np.int64), dim=2)
        zero = np.zeros(2)
        options = NewtonOptions(max_iterations=6, line_search=0)
        return newton_step(model, np.zeros(2), 0.0, 1.0, Loads(np.zeros(0), np.zeros(0), zero, zero),
                           make_solver("superlu"), options)

    res = run([0, 4, 3, 5, 2, 1])
    assert res.converged and res.iterations == 4 and res.residuals[-1] == pytest.approx(3e-9)
    assert res.energies[-1] > 1e-10  # the energy norm alone would not have converged
    res = run([0, 0, 0, 0, 2, 1])  # switched only at that iterate: not unsettled
    assert not res.converged and len(res.residuals) > 5
