"""Crack maps: which cracks are drawn, where, and with which opening."""

import numpy as np
import pytest

from rockfrac.output.crack_map import crack_lines, save_crack_map
from rockfrac.output.vtk import CrackState, step_fields


def _two_quads_and_a_crack(state, plastic_jump):
    """Two unit quads stacked, split along y = 1 (nodes 2, 3 below; 4, 5 above), the top one
    lifted by 0.1 and shifted by 0.05; an embedded segment across the lower cell."""
    nodes = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0, 1], [1, 1], [1, 2], [0, 2]], float)
    cells = np.array([[0, 1, 2, 3], [4, 5, 6, 7]])
    disp = np.zeros((8, 2))
    disp[4:] = [0.05, 0.1]
    return step_fields(
        nodes, cells, "quad4", interfaces=np.array([[3, 2, 4, 5]]),
        segments=(np.array([[0.0, 0.2]]), np.array([[1.0, 0.6]])), segment_cells=np.array([0]),
        point_data={"displacement": disp}, bulk_data={"gamma": np.array([0.0, 0.01])},
        interface_data={"jump": np.array([[0.05, 0.1]]), "plastic_jump": np.array([plastic_jump]),
                        "state": np.array([state], dtype=np.int8)},
        segment_data={"jump": np.array([[3e-3, 4e-3]]), "state": np.array([CrackState.PLASTIC], dtype=np.int8)})


def test_a_yielded_interface_is_drawn_on_the_midline_of_its_deformed_faces_with_its_opening():
    f = _two_quads_and_a_crack(CrackState.PLASTIC, [0.01, 0.02])
    c = crack_lines(f, magnification=2.0)
    assert c.segments.shape == (2, 2, 2)
    # interface: minus face at y = 1, plus face at y = 1 + 2 x 0.1, shifted by 2 x 0.05 -> midline
    np.testing.assert_allclose(c.segments[0], [[0.05, 1.1], [1.05, 1.1]], atol=1e-15)
    np.testing.assert_allclose(c.opening, [np.hypot(0.05, 0.1), 5e-3], rtol=1e-14)
    # embedded: its end points, moved with the (zero) continuous displacement of the lower cell
    np.testing.assert_allclose(c.segments[1], [[0.0, 0.2], [1.0, 0.6]], atol=1e-15)


@pytest.mark.parametrize("state,plastic_jump,drawn", [
    (CrackState.ELASTIC, [0.0, 0.0], 1),  # never yielded: only the embedded segment
    (CrackState.ELASTIC, [1e-6, 0.0], 2),  # yielded before, unloaded now: still a crack
    (CrackState.CONSTRAINED, [0.0, 0.0], 1),
])
def test_only_interfaces_that_have_yielded_are_cracks(state, plastic_jump, drawn):
    c = crack_lines(_two_quads_and_a_crack(state, plastic_jump), magnification=1.0)
    assert c.opening.size == drawn


def test_the_picture_is_written_and_a_wrong_field_is_named(tmp_path):
    f = _two_quads_and_a_crack(CrackState.PLASTIC, [0.01, 0.0])
    c = save_crack_map(tmp_path / "m.png", f, 1.0)
    assert (tmp_path / "m.png").stat().st_size > 1000 and c.opening.size == 2
    with pytest.raises(ValueError, match="unknown cell field 'damage'; known: .*gamma"):
        save_crack_map(tmp_path / "n.png", f, 1.0, cell_field="damage")


def test_the_hexahedron_of_the_paper_draws_its_embedded_crack(tmp_path):
    """The paper's EDE (one Hex8 in plane strain) past localization: the crack map and the ParaView
    fields carry its surface's trace on the z = 0 face, across the cell at the band angle, with the
    cell's jump (issue 15: the hex8 crack map was empty)."""
    import math

    from rockfrac.case.schema import parse_case
    from rockfrac.output.fields import step_output
    from rockfrac.runner import run_case
    from rockfrac.studies import table1

    s = run_case(parse_case(table1.ede_case(axial_steps=300), "ede"), tmp_path / "o", overwrite=True)
    g = s.built.embeddeds[0]
    assert g.localized().tolist() == [0]
    f = step_output(s.built, s.result.u)
    c = crack_lines(f, magnification=0.0)  # undeformed: the trace itself
    assert c.segments.shape == (1, 2, 2)
    (x0, y0), (x1, y1) = sorted(map(tuple, c.segments[0]))
    assert x0 == pytest.approx(0.0, abs=1e-12) and x1 == pytest.approx(0.04, abs=1e-12)  # across the cell
    n = g.e_state[0, 1:4]
    assert abs(n[2]) < 1e-12
    assert math.degrees(math.atan2(y1 - y0, x1 - x0)) == pytest.approx(math.degrees(math.atan2(-n[0], n[1])), abs=1e-9)
    jump = g.records()
    assert c.opening[0] == pytest.approx(math.hypot(jump["jump_t"][0], jump["jump_n"][0]), rel=1e-12)
    assert c.opening[0] > 1e-4
    assert "1 crack segments" in (tmp_path / "o" / "run.log").read_text()
    # a surface with a normal out of the x-y plane has no trace drawn (3D cracks are issue 16's)
    g.sections[0] = np.nan
    assert crack_lines(step_output(s.built, s.result.u), 0.0).segments.shape == (0, 2, 2)
