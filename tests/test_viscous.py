"""Viscous (Duvaut-Lions) regularisation of the EP and RP cohesive surfaces ([cohesive] viscosity): a
consistent tangent, convergence to the rate-independent law as the relaxation time shrinks,
relaxation to it under a held load, a snap-back passed under load control with the energy it
releases reported as D_viscous, and the keys checked."""

import tomllib
from pathlib import Path

import numpy as np
import pytest

from rockfrac.case.schema import CaseError, parse_case
from rockfrac.output.csvout import read_csv
from rockfrac.runner import run_case
from test_rock_tests import elastic_start

ROOT = Path(__file__).resolve().parents[1]
WIDTH, GC, SIGMA_C = 0.01, 100.0, 1e6  # m, J/m^2, Pa: delta_c = 2 Gc / sigma_c = 0.2 mm


def bar(height: float, pull: float, steps: int, viscosity: float | None, hold: int = 0, young: float = 1e10,
        form: str = "ep") -> dict:
    """A 1 x 2 block whose one internal edge carries a bilinear surface (EP, or RP with the EP's
    penalty as augmentation), pulled at its top (load control), then optionally held there for
    ``hold`` steps of one more stage."""
    coh = {"law": "bilinear", "form": form, "where": "all", "sigma_c": SIGMA_C, "Gc": GC}
    coh.update({"kn": 1e13, "kt": 1e13} if form == "ep" else {"augmentation": 1e13})
    if viscosity is not None:
        coh["viscosity"] = viscosity
    fixed = {"bottom": {"y": 0.0}, "bottom_left": {"x": 0.0}}
    stages = [{"name": "pull", "steps": steps, "displacement": {**fixed, "top": {"x": 0.0, "y": pull}}}]
    if hold:  # until the load has relaxed to nothing (or to a rate-independent residue: the whole stage)
        stages.append({"name": "hold", "steps": hold, "displacement": {**fixed, "top": {"x": 0.0, "y": pull}},
                       "stop": {"quantity": "R_top_y", "below_peak_fraction": 1e-6}})
    return {"mesh": {"kind": "block", "element": "quad4", "width": WIDTH, "height": height, "nx": 1, "ny": 2},
            "bulk": {"E": young, "nu": 0.0}, "cohesive": coh, "stages": stages,
            "output": {"vtk": False, "picture": False, "points": False}}


def run(tmp_path, name: str, d: dict):
    out = tmp_path / name
    s = run_case(parse_case(d), out)
    return s, read_csv(out / "history.csv")


@pytest.fixture(scope="module")
def short_bar(tmp_path_factory):
    """A stiff short bar (no snap-back: bulk E / h = 5e11 Pa/m against a softening slope of 5e9)
    pulled to 0.3 mm, then held: rate-independent and two relaxation times, eta << a step (1/150):
    the overstress ~ eta kn d[[u]]/dt is a few % of sigma_c."""
    tmp = tmp_path_factory.mktemp("viscous")
    return {eta: run(tmp, f"eta{eta}", bar(0.02, 3e-4, 150, eta, hold=40)) for eta in (None, 2e-5, 1e-5)}


def test_viscous_converges_to_the_rate_independent_law_linearly(short_bar):
    """The force's largest departure from the rate-independent one (during the softening, where the
    overstress lives) and the extra dissipation both halve when the relaxation time halves."""
    _, ref = short_bar[None]
    assert "D_viscous" not in ref
    pull = ref["stage"] == "pull"
    err, dv = [], []
    for eta in (2e-5, 1e-5):
        s, h = short_bar[eta]
        assert s.result.completed
        at = h["stage"] == "pull"  # at equal top displacement (the runs' steps differ where they cut back)
        rate_independent = np.interp(h["u_top_y"][at], ref["u_top_y"][pull], ref["R_top_y"][pull])
        err.append(np.abs(h["R_top_y"][at] - rate_independent).max())
        dv.append(h["D_viscous"][-1])
    assert err[0] > 0.01 * np.abs(ref["R_top_y"]).max()  # a visible regularisation ...
    assert 1.7 < err[0] / err[1] < 2.3  # ... first order in eta
    assert all(d > 0.0 for d in dv) and 1.7 < dv[0] / dv[1] < 2.3


def test_viscous_relaxes_to_the_rate_independent_state_under_a_held_load(short_bar):
    """After the hold (40 steps of 1/40, each > 1000 relaxation times) the force, the law's own
    dissipation (G_c W: the surface has separated) and the energy balance are the
    rate-independent ones, and D_dissipated = D_surface_law + D_viscous to the time integration."""
    _, ref = short_bar[None]
    for eta in (2e-5, 1e-5):
        _, h = short_bar[eta]
        assert h["R_top_y"][-1] == pytest.approx(ref["R_top_y"][-1], abs=1e-9 * np.abs(ref["R_top_y"]).max())
        assert h["D_surface_law"][-1] == pytest.approx(GC * WIDTH, rel=1e-9)
        assert h["D_dissipated"][-1] - h["D_viscous"][-1] == pytest.approx(GC * WIDTH, rel=1.5e-2)
        assert abs(h["energy_error"][-1]) < 1e-9 * h["D_dissipated"][-1]


@pytest.mark.parametrize("form", ["ep", "rp"])
def test_viscous_passes_a_snap_back_under_load_control(tmp_path, form):
    """A long soft bar (bulk E / h = 1e9 Pa/m in series with a softening slope of -5e9: snap-back,
    the bar stores 5 G_c W at the peak) under load control: the rate-independent run cannot pass
    the peak (it stops cleanly at min_step), the viscous one separates; the elastic energy the
    snap-back releases goes to D_viscous: W_external = G_c W + D_viscous at separation (bulk
    unloaded), within 1.5 %. EP and RP alike (RP's overstress relaxes over eta r, r the
    augmentation: the EP's penalty here)."""
    s_ref, ref = run(tmp_path, "ref", bar(1.0, 2e-3, 40, None, young=1e9, form=form))
    assert not s_ref.result.completed and ref["R_top_y"].size > 0
    s, h = run(tmp_path, "visc", bar(1.0, 2e-3, 40, 1e-6, hold=40, young=1e9, form=form))
    assert s.result.completed and "fell below" in s.result.message
    assert np.abs(h["R_top_y"][-1]) < 1e-6 * np.abs(h["R_top_y"]).max()
    assert h["D_surface_law"][-1] == pytest.approx(GC * WIDTH, rel=1e-9)
    assert h["D_viscous"][-1] > 2 * GC * WIDTH  # a snap-back: most of the stored energy is released
    assert h["W_external"][-1] == pytest.approx(h["D_dissipated"][-1], rel=1e-9)  # the bar has unloaded
    # the work account integrates T . d[[u_p]] by the trapezoidal rule, D_viscous likewise on the
    # overstress; the law's own account is exact: they differ by the rule's error over the largest
    # steps of the snap-back (0.8 % here, the same for 40 to 160 nominal steps)
    assert h["W_external"][-1] == pytest.approx(GC * WIDTH + h["D_viscous"][-1], rel=1.5e-2)


def assert_tangent_by_differences(g, ke, u1, u0, points, h, h_extra=1.0):
    """ke of the group's points against central differences of their fe, step h [m] on the
    displacements (h_extra [Pa] on an RP point's multipliers)."""
    for i in points:
        for j, dof in enumerate(g.dofs[i]):
            step = h if j < g.points.dofs.shape[1] else h_extra
            up, um = u1.copy(), u1.copy()
            up[dof] += step
            um[dof] -= step
            g.begin_step()
            fp = g.evaluate(up, u0).fe[i].copy()
            g.begin_step()
            fm = g.evaluate(um, u0).fe[i].copy()
            fd = (fp - fm) / (2 * step)
            assert np.allclose(ke[i][:, j], fd, rtol=1e-5, atol=1e-6 * np.abs(ke[i]).max())


@pytest.mark.parametrize("form", ["ep", "rp"])
def test_viscous_tangent_matches_finite_differences(tmp_path, form):
    """ke of the regularised points against central differences of fe, mid-softening, a in (0, 1);
    RP: the multipliers' rows and columns too."""
    s, _ = run(tmp_path, "partial", bar(0.02, 1.2e-4, 60, 1e-5, form=form))
    g = next(g for g in s.built.model.groups if g.kind == "cohesive")
    assert g.any_plastic()
    u0 = s.result.u.copy()
    top = g.points.dofs[:, 3]  # the plus side's y dofs: open the surface further
    u1 = u0.copy()
    u1[top] += 2e-6
    g.set_step("load", 1e-5)
    assert 0.0 < g.blend() < 1.0
    g.begin_step()
    ev = g.evaluate(u1, u0)
    assert ev.ok and np.all(g.trial[:, g.mode] == 1.0)
    assert_tangent_by_differences(g, ev.ke, u1, u0, range(g.points.n), 1e-11)


def test_viscous_brazilian_disc_splits_under_load_control(tmp_path):
    """examples/rock_tests/brazilian/everywhere_viscous: surfaces on every edge, load control. The
    peak is within 2 % of the rate-independent disc's (everywhere.toml, path control: 621 kN/m), with
    the regularisation's share of the dissipation small up to it; the run goes on to below half the
    peak (rate-independent load steps stop at it), the energy balance closes and D_viscous carries
    what the snap-back releases."""
    path = ROOT / "examples" / "rock_tests" / "brazilian" / "everywhere_viscous.toml"
    d = tomllib.loads(path.read_text())
    d["mesh"]["file"] = str(path.parent / d["mesh"]["file"])
    # the first surface yields at 0.45 of the stage: one (elastic) step to 0.4 of its displacement,
    # then the rest at the example's load step, the relaxation time scaled to the shorter stage (the same
    # 1e-10 m of the platen's travel: history.csv's time is a stage's load factor)
    elastic_start(d, 0.4)
    d["cohesive"]["viscosity"] /= 0.6
    d["solver"] = {"max_iterations": 20}  # converged steps take at most 15: failed ones stop sooner
    s, h = run(tmp_path, "disc", d)
    assert s.result.completed and "fell below 0.5" in s.result.message
    r = np.abs(h["R_load_top_y"])
    peak = int(np.argmax(r))
    assert r[peak] == pytest.approx(620.6e3, rel=0.02)
    assert h["D_viscous"][peak] < 0.1 * h["D_surface_law"][peak]
    assert h["D_viscous"][-1] > h["D_surface_law"][-1] > 0.0
    assert abs(h["energy_error"][-1]) < 1e-9 * h["W_external"][-1]
    assert "D_viscous" in (tmp_path / "disc" / "run.log").read_text()


@pytest.mark.parametrize("edit,expected", [
    ({"cohesive": {"viscosity": 0.0}}, "viscosity"),
    ({"cohesive": {"viscosity": -1.0}}, "viscosity"),
    ({"cohesive": {"integration": "implex"}}, "viscosity regularises the implicit update"),
    ({"solver": {"fallback": "implex"}}, "two regularisations"),
    ({"stages": "path"}, "stage 'pull' has control = 'path'"),
])
def test_viscous_keys_are_checked(edit, expected):
    d = bar(0.02, 3e-4, 10, 0.01)
    for section, values in edit.items():
        if section == "stages":
            d["stages"][0]["control"] = values
        else:
            d.setdefault(section, {}).update(values)
    with pytest.raises(CaseError) as err:
        parse_case(d, "c.toml")
    assert expected in str(err.value) and "c.toml" in str(err.value)


@pytest.mark.parametrize("form", ["ep", "rp"])
def test_viscous_3d_surface_tangent_matches_finite_differences(tmp_path, form):
    """The Duvaut-Lions update of 3D interfaces (the jointed triaxial cylinder, sliding): ke against
    central differences of fe for an oblique increment (along the strike and the dip), a in (0, 1);
    RP: the multipliers' rows and columns too."""
    root = Path(__file__).resolve().parents[1] / "examples" / "rock_tests" / "triaxial"
    d = tomllib.loads((root / "joint.toml").read_text())
    d["mesh"]["file"] = str(root / d["mesh"]["file"])
    d["cohesive"]["viscosity"] = 1e-3
    if form == "rp":
        d["cohesive"].update(form="rp", augmentation=d["cohesive"].pop("kn"))
        d["cohesive"].pop("kt")
    # the joint holds (elastic) to about 1.25e-4 m: in two steps to 1e-4, then steps of 1e-5 (sliding)
    d["stages"][1].update(steps=2, displacement={"top": {"z": -1e-4}})
    d["stages"].append({"name": "slide", "steps": 6, "displacement": {"top": {"z": -1.6e-4}}})
    d["output"] = {"picture": False, "points": False}
    s = run_case(parse_case(d, "joint.toml"), tmp_path / "o")
    assert s.result.completed
    g = next(g for g in s.built.model.groups if g.kind == "cohesive")
    assert g.dim == 3 and g.any_plastic() and g.viscous_energy() > 0.0
    u0 = s.result.u.copy()
    u1 = u0.copy()
    plus = g.points.dofs[:, 3:]
    u1[plus[:, 0]] += 3e-10  # along x (down the dip's horizontal part) and y (the strike)
    u1[plus[:, 1]] += 2e-10
    u1[plus[:, 2]] -= 1e-10
    g.set_step("load", 1e-3)
    assert 0.2 < g.blend() < 0.8
    g.begin_step()
    ev = g.evaluate(u1, u0)
    assert ev.ok and np.all(g.trial[:, g.mode] == 1.0)
    assert_tangent_by_differences(g, ev.ke, u1, u0, range(0, g.points.n, 7), 1e-14)
