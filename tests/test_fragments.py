"""Fragments of a mesh with cohesive surfaces (rockfrac.output.fragments): a body is cut into pieces
only where a crack of separated pairs closes round them; a crack that stops inside the mesh, or one
pair that still holds, leaves it whole."""

import numpy as np
import pytest

from rockfrac.case.schema import CaseError, parse_case
from rockfrac.mesh import Mesh
from rockfrac.mesh.interfaces import all_edges, insert_interfaces
from rockfrac.mesh.interfaces_3d import all_faces, insert_faces
from rockfrac.output.csvout import read_csv
from rockfrac.output.fragments import Fragments
from rockfrac.runner import run_case
from test_interfaces import grid


def split_grid(n: int, tri: bool = False) -> Mesh:
    """The unit square of n x n quads (or 2 n^2 triangles), a surface on every internal edge."""
    m = grid(n, n, tri=tri)
    return insert_interfaces(m, all_edges(m))


def pairs_where(mesh: Mesh, keep) -> np.ndarray:
    """The (minus, plus) pairs of the interface cells whose minus side's midpoint passes ``keep``."""
    half = mesh.interfaces.shape[1] // 2
    mid = mesh.nodes[mesh.interfaces[:, :half]].mean(axis=1)
    hit = mesh.interfaces[keep(mid)]
    return np.concatenate([np.stack([hit[:, j], hit[:, half + j]], axis=1) for j in range(half)])


@pytest.mark.parametrize("tri", [False, True])
def test_an_intact_mesh_is_one_fragment_and_every_pair_broken_makes_every_cell_one(tri):
    m = split_grid(4, tri)
    f = Fragments(m)
    whole = f.pieces(np.zeros((0, 2), dtype=np.int64))
    assert whole.count == 1 and whole.size[0] == pytest.approx(1.0, rel=1e-12)
    assert whole.centroid[0] == pytest.approx([0.5, 0.5], rel=1e-12)
    every = f.pieces(pairs_where(m, lambda x: np.ones(x.shape[0], dtype=bool)))
    assert every.count == m.cells.shape[0]
    assert np.allclose(every.size, 1.0 / m.cells.shape[0], rtol=1e-12) and np.all(every.cells == 1)


def test_a_crack_across_cuts_two_pieces_and_one_stopping_inside_or_held_at_one_pair_does_not():
    m = split_grid(4)
    f = Fragments(m)
    vertical = lambda x: np.isclose(x[:, 0], 0.25) & (np.abs(x[:, 1] - 0.5) < 1.0)  # noqa: E731
    through = pairs_where(m, vertical)  # the line x = 0.25 from the bottom to the top
    two = f.pieces(through)
    assert two.count == 2
    assert two.size == pytest.approx([0.75, 0.25], rel=1e-12)  # the largest first
    assert two.centroid[0] == pytest.approx([0.625, 0.5], rel=1e-12)
    assert two.centroid[1] == pytest.approx([0.125, 0.5], rel=1e-12)
    assert np.all(two.cell_fragment[np.isclose(m.nodes[m.cells].mean(axis=1)[:, 0], 0.125)] == 1)
    stops = pairs_where(m, lambda x: np.isclose(x[:, 0], 0.25) & (x[:, 1] < 0.7))  # three of four edges
    assert f.pieces(stops).count == 1
    middle = np.isclose(m.nodes[through[:, 0], 1], 0.5)  # the pair at (0.25, 0.5), in both of its cells
    assert middle.sum() == 2
    held = through[~middle]  # every pair of the line but one
    assert f.pieces(held).count == 1
    assert f.pieces(held[:, ::-1]).count == 1  # the pairs' nodes in either order
    assert f.pieces(through[:, ::-1]).count == 2


def test_a_block_cut_by_two_crossing_cracks_falls_into_four():
    m = split_grid(4, tri=True)
    f = Fragments(m)
    cross = pairs_where(m, lambda x: np.isclose(x[:, 0], 0.5) | np.isclose(x[:, 1], 0.5))
    four = f.pieces(cross)
    assert four.count == 4 and four.size == pytest.approx([0.25] * 4, rel=1e-12)
    assert sorted(map(tuple, np.round(four.centroid, 12))) == [(0.25, 0.25), (0.25, 0.75), (0.75, 0.25), (0.75, 0.75)]


def test_a_hexahedral_box_cut_by_a_plane_falls_into_two():
    n = 3
    x, y, z = np.meshgrid(*(np.linspace(0.0, 1.0, n + 1),) * 3, indexing="ij")
    ids = np.arange((n + 1) ** 3).reshape(n + 1, n + 1, n + 1)
    i, j, k = (a.ravel() for a in np.meshgrid(*(np.arange(n),) * 3, indexing="ij"))
    cells = np.stack([ids[i, j, k], ids[i + 1, j, k], ids[i + 1, j + 1, k], ids[i, j + 1, k],
                      ids[i, j, k + 1], ids[i + 1, j, k + 1], ids[i + 1, j + 1, k + 1], ids[i, j + 1, k + 1]], axis=1)
    m = insert_faces(Mesh(np.column_stack([x.ravel(), y.ravel(), z.ravel()]), cells, "hex8"),
                     all_faces(Mesh(np.column_stack([x.ravel(), y.ravel(), z.ravel()]), cells, "hex8")))
    f = Fragments(m)
    assert f.pieces(np.zeros((0, 2), dtype=np.int64)).count == 1
    plane = f.pieces(pairs_where(m, lambda c: np.isclose(c[:, 2], 1.0 / 3.0)))
    assert plane.count == 2 and plane.size == pytest.approx([2.0 / 3.0, 1.0 / 3.0], rel=1e-12)
    assert plane.centroid[1] == pytest.approx([0.5, 0.5, 1.0 / 6.0], rel=1e-12)


def pulled_block(fraction: float | None) -> dict:
    """The 4 x 2 block of tests/test_implex.py, bilinear EP surfaces on every internal edge, pulled."""
    d = {"mesh": {"kind": "block", "element": "quad4", "width": 0.04, "height": 0.02, "nx": 4, "ny": 2},
         "bulk": {"E": 1e10, "nu": 0.2},
         "cohesive": {"law": "bilinear", "form": "ep", "where": "all", "sigma_c": 1e6, "Gc": 100.0, "kn": 1e14,
                      "kt": 1e14},
         "stages": [{"name": "pull", "steps": 100, "control": "path", "max_steps": 3000,
                     "displacement": {"bottom": {"y": 0.0}, "bottom_left": {"x": 0.0}, "top": {"x": 0.0, "y": 1e-3}},
                     "stop": {"quantity": "R_top_y", "below_peak_fraction": 1e-6}}],
         "output": {"vtk": False, "picture": False, "points": False}}
    if fraction is not None:
        d["output"]["separated_fraction"] = fraction
    return d


def test_the_separated_fraction_sets_when_a_pair_lets_go(tmp_path):
    """With [output] separated_fraction = 0.5 the block falls in two once its surfaces have lost half
    their strength, at half the peak load (the bilinear law: the load falls with the strength); with
    the default 1 %, at 1 % of it; run.log names the step and the pieces. The fraction is checked."""
    loads = {}
    for fraction in (None, 0.5):
        run_case(parse_case(pulled_block(fraction)), tmp_path / str(fraction))
        h = read_csv(tmp_path / str(fraction) / "history.csv")
        r = np.abs(h["R_top_y"])
        first = int(np.argmax(h["n_fragments"] == 2))
        assert h["n_fragments"][first - 1] == 1 and h["n_fragments"][-1] == 2
        loads[fraction] = (r[first - 1] / r.max(), r[first] / r.max())
        log = (tmp_path / str(fraction) / "run.log").read_text()  # the step it broke, and the pieces at the end
        assert "model: 8 quad4 cells, 32 nodes, 10 interface cells, 64 unknowns" in log  # split on every edge
        assert [line for line in log.splitlines() if "fragments" in line] == [
            f"  fragments at step {int(h['step'][first])}: the body is in 2 pieces (was 1), "
            f"separated = {h['separated'][first]:.6g}",
            "fragments: the body ends in 2 pieces of 0.0004, 0.0004 m^2 (fragments.csv)"]
    assert loads[0.5][1] <= 0.5 + 1e-9 and loads[0.5][0] > 0.5  # it lets go in the step that crosses half
    assert loads[None][1] <= 0.01 + 1e-9 and loads[None][0] > 0.01
    for bad in (0.0, 1.0, -0.1, "half"):
        with pytest.raises(CaseError, match="separated_fraction"):
            parse_case(pulled_block(bad), "c.toml")  # type: ignore[arg-type]


def test_a_resumed_run_logs_the_break_as_the_uninterrupted_one(tmp_path):
    """Resumed from a checkpoint after the block broke, run.log says what the uninterrupted run's says:
    the break once, not again at the first resumed step (the pieces at the checkpoint come from its
    history)."""
    from test_resume_and_vtk import interrupted_then_resumed

    d = pulled_block(0.5)
    run_case(parse_case(d), tmp_path / "full")
    h = read_csv(tmp_path / "full" / "history.csv")
    broke = int(h["step"][np.argmax(h["n_fragments"] == 2)])
    d["output"]["checkpoint_every"] = broke + 1
    interrupted_then_resumed(parse_case(d), tmp_path, at=broke + 3)

    def lines(folder: str) -> list[str]:
        return [x for x in (tmp_path / folder / "run.log").read_text().splitlines() if "fragments" in x]

    assert lines("cut") == lines("full") and len(lines("full")) == 2
    assert f"resumed from the checkpoint at step {broke + 1}" in (tmp_path / "cut" / "run.log").read_text()
