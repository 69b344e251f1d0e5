"""ParaView output: VTU files read back with meshio, the .pvd collection, truncation on resume."""

import xml.etree.ElementTree as ET

import meshio
import numpy as np
import pytest

from rockfrac.output.vtk import (
    CellKind,
    StepFields,
    VtkSeries,
    crack_segments_from_points,
    interpolate_nodal,
    pad_cell_data,
    piece_of,
    step_fields,
)

# two unit quads side by side, split at x = 1 by a zero-thickness interface (t = -y, n = +x)
NODES = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [1, 0], [2, 0], [2, 1], [1, 1]], dtype=float)
QUADS = np.array([[0, 1, 2, 3], [4, 5, 6, 7]])
INTERFACE = np.array([[2, 1, 7, 4]])  # (m0, m1, p0, p1)
X0, X1 = np.array([[0.0, 0.25]]), np.array([[1.0, 0.75]])  # an embedded crack in cell 0
A = np.array([[1e-3, 2e-3], [3e-3, -1e-3]])


def displacement(step: int) -> np.ndarray:
    """Linear in each cell; the right cell also moves 1e-2 in x (the interface opens)."""
    u = NODES @ A.T
    u[4:, 0] += 1e-2
    return step * u


def fields_2d(step: int) -> StepFields:
    return step_fields(
        NODES, QUADS, "quad4", interfaces=INTERFACE, segments=(X0, X1), segment_cells=[0],
        point_data={"displacement": displacement(step)},
        bulk_data={"stress": step * np.arange(12.0).reshape(2, 6), "gamma": np.array([0.0, step]),
                   "localized": np.array([1, 0])},
        interface_data={"jump": step * np.array([[0.0, 1e-2]]), "traction": np.array([[1.0, 2.0]]),
                        "state": np.array([2])},
        segment_data={"jump": np.array([[step * 1e-3, 0.0]]), "c": np.array([9053.0])},
    )


def by_type(mesh: meshio.Mesh, name: str | None = None) -> dict[str, np.ndarray]:
    """Cells (or a cell field) per cell type, joined over blocks (meshio merges same-type runs)."""
    out: dict[str, list[np.ndarray]] = {}
    for k, block in enumerate(mesh.cells):
        data = block.data if name is None else mesh.cell_data[name][k]
        out.setdefault(block.type, []).append(data)
    return {t: np.concatenate(v) for t, v in out.items()}


def pvd_entries(path) -> list[tuple[float, str]]:
    root = ET.parse(path).getroot()
    assert root.get("type") == "Collection"
    return [(float(d.get("timestep")), d.get("file")) for d in root.iter("DataSet")]


def test_2d_series_reads_back(tmp_path):
    series = VtkSeries(tmp_path / "vtk")
    times = [0.0, 0.5, 1.25]
    for step, time in enumerate(times):
        series.write(step, time, fields_2d(step))

    assert pvd_entries(tmp_path / "vtk" / "results.pvd") == [
        (t, f"results_{s:05d}.vtu") for s, t in enumerate(times)]
    for step in range(3):
        m = meshio.read(tmp_path / "vtk" / f"results_{step:05d}.vtu")
        # points: the 8 nodes with z = 0, then the segment's two extra points
        np.testing.assert_array_equal(m.points[:, :2], np.vstack([NODES, X0, X1]))
        np.testing.assert_array_equal(m.points[:, 2], 0.0)
        cells = by_type(m)
        np.testing.assert_array_equal(cells["quad"], [[0, 1, 2, 3], [4, 5, 6, 7], [2, 1, 4, 7]])
        np.testing.assert_array_equal(cells["line"], [[8, 9]])
        # displacement padded to 3D; at the extra points the linear field of cell 0 (N d)
        u = m.point_data["displacement"]
        assert u.shape == (10, 3)
        np.testing.assert_allclose(u[:8, :2], displacement(step))
        np.testing.assert_allclose(u[8:, :2], step * np.vstack([X0, X1]) @ A.T, atol=1e-15)
        np.testing.assert_array_equal(u[:, 2], 0.0)
        # cell data: every field on every cell, NaN where a kind lacks it
        kind = by_type(m, "cell_kind")
        np.testing.assert_array_equal(kind["quad"],
                                      [CellKind.BULK, CellKind.BULK, CellKind.INTERFACE])
        np.testing.assert_array_equal(kind["line"], [CellKind.EMBEDDED])
        stress = by_type(m, "stress")
        np.testing.assert_array_equal(stress["quad"][:2], step * np.arange(12.0).reshape(2, 6))
        assert np.isnan(stress["quad"][2]).all() and np.isnan(stress["line"]).all()
        jump = by_type(m, "jump")
        assert np.isnan(jump["quad"][:2]).all()
        np.testing.assert_array_equal(jump["quad"][2], [0.0, step * 1e-2])
        np.testing.assert_array_equal(jump["line"], [[step * 1e-3, 0.0]])
        state = by_type(m, "state")
        np.testing.assert_array_equal(state["quad"], [np.nan, np.nan, 2.0])
        np.testing.assert_array_equal(state["line"], [np.nan])
        np.testing.assert_array_equal(by_type(m, "c")["line"], [9053.0])
        np.testing.assert_array_equal(by_type(m, "localized")["quad"], [1, 0, np.nan])
        assert set(m.cell_data) == {"stress", "gamma", "localized", "jump", "traction", "state",
                                    "c", "cell_kind"}

    # the interface quad opens under the warp: its plus edge moved 1e-2 further in x
    warped = m.points[:, :2] + u[:, :2]
    quad = cells["quad"][2]
    np.testing.assert_allclose(warped[quad[2:], 0] - warped[quad[1::-1], 0], 2 * 1e-2)


def test_truncate_and_resume(tmp_path):
    folder = tmp_path / "vtk"
    series = VtkSeries(folder)
    for step in range(3):
        series.write(step, 0.1 * step, fields_2d(step))
    series.truncate_after(1)
    assert pvd_entries(folder / "results.pvd") == [(0.0, "results_00000.vtu"),
                                                    (0.1, "results_00001.vtu")]
    assert sorted(p.name for p in folder.iterdir()) == ["results.pvd", "results_00000.vtu",
                                                        "results_00001.vtu"]
    with pytest.raises(ValueError, match="step 1 is not after the last written step 1"):
        series.write(1, 0.1, fields_2d(1))

    # another process resumes from the .pvd; an orphan VTU beyond it is deleted by truncation
    (folder / "results_00007.vtu").write_text("orphan")
    resumed = VtkSeries(folder, resume=True)
    assert [e[0] for e in resumed.entries] == [0, 1]
    resumed.truncate_after(0)
    resumed.write(1, 0.2, fields_2d(1))
    assert pvd_entries(folder / "results.pvd") == [(0.0, "results_00000.vtu"),
                                                    (0.2, "results_00001.vtu")]
    assert not (folder / "results_00007.vtu").exists()
    assert not list(folder.glob(".*"))  # no temporary files left

    # a new series in the same folder starts empty and removes the old files
    VtkSeries(folder)
    assert pvd_entries(folder / "results.pvd") == []
    assert sorted(p.name for p in folder.iterdir()) == ["results.pvd"]


def test_3d_hexahedra(tmp_path):
    x, y, z = np.meshgrid([0.0, 1.0, 2.0], [0.0, 1.0], [0.0, 0.5], indexing="ij")
    nodes = np.column_stack([x.ravel(), y.ravel(), z.ravel()])
    idx = np.arange(12).reshape(3, 2, 2)  # (ix, iy, iz)

    def hex_at(i):
        bottom = [idx[i, 0, 0], idx[i + 1, 0, 0], idx[i + 1, 1, 0], idx[i, 1, 0]]
        return bottom + [idx[i, 0, 1], idx[i + 1, 0, 1], idx[i + 1, 1, 1], idx[i, 1, 1]]

    hexes = np.array([hex_at(0), hex_at(1)])
    u = nodes @ np.array([[1e-3, 0, 0], [0, -2e-3, 0], [0, 0, 0]]).T
    fields = step_fields(nodes, hexes, "hex8", segments=(X1[:, :2] + [1, 0], X0 + [2, 0]),
                         segment_cells=[1], point_data={"displacement": u},
                         bulk_data={"stress": np.ones((2, 6))},
                         segment_data={"jump": np.ones((1, 2))})
    series = VtkSeries(tmp_path, name="hex")
    series.write(3, 2.0, fields)
    m = meshio.read(tmp_path / "hex_00003.vtu")
    np.testing.assert_array_equal(m.points[:12], nodes)
    np.testing.assert_array_equal(m.points[12:], [[2.0, 0.75, 0.0], [2.0, 0.25, 0.0]])
    cells = by_type(m)
    np.testing.assert_array_equal(cells["hexahedron"], hexes)
    np.testing.assert_array_equal(cells["line"], [[12, 13]])
    np.testing.assert_allclose(m.point_data["displacement"], np.vstack([u, m.points[12:] @ [
        [1e-3, 0, 0], [0, -2e-3, 0], [0, 0, 0]]]), atol=1e-15)
    np.testing.assert_array_equal(by_type(m, "stress")["line"], np.full((1, 6), np.nan))
    np.testing.assert_array_equal(by_type(m, "jump")["hexahedron"], np.full((2, 2), np.nan))
    assert pvd_entries(tmp_path / "hex.pvd") == [(2.0, "hex_00003.vtu")]


def test_pad_cell_data_and_segments():
    out = pad_cell_data([2, 3], [{"a": np.ones((2, 6)), "k": np.array([1, 2])},
                                 {"b": np.zeros(3), "k": np.array([3, 4, 5])}])
    assert out["a"][1].shape == (3, 6) and np.isnan(out["a"][1]).all()
    assert np.isnan(out["b"][0]).all() and out["b"][0].shape == (2,)
    assert out["k"][0].dtype.kind == "i"  # present everywhere: dtype kept
    with pytest.raises(ValueError, match="components"):
        pad_cell_data([1, 1], [{"a": np.ones((1, 2))}, {"a": np.ones((1, 3))}])
    with pytest.raises(ValueError, match="2 rows for 3 cells"):
        pad_cell_data([3], [{"a": np.ones(2)}])

    pts, lines = crack_segments_from_points(np.zeros((2, 2)), np.ones((2, 2)), offset=5)
    assert pts.shape == (4, 3)
    np.testing.assert_array_equal(pts[:, 0], [0, 1, 0, 1])
    np.testing.assert_array_equal(lines, [[5, 6], [7, 8]])

    with pytest.raises(ValueError, match="cell field 'a' has blocks of"):
        StepFields(NODES, [("quad", QUADS)], cell_data={"a": [np.ones(3)]})
    with pytest.raises(ValueError, match="unknown cell type 'quad8'"):
        step_fields(NODES, QUADS, "quad8")


def test_interpolation_in_distorted_cells():
    rng = np.random.default_rng(0)
    nodes = np.array([[0.0, 0.0], [2.0, 0.3], [2.5, 1.8], [-0.4, 1.2]])
    cells = np.array([[0, 1, 2, 3]])
    xi = rng.uniform(-1, 1, (50, 2))
    n = 0.25 * (1 + np.outer(xi[:, 0], [-1, 1, 1, -1])) * (1 + np.outer(xi[:, 1], [-1, -1, 1, 1]))
    x = n @ nodes
    f = rng.normal(size=(4, 3))
    np.testing.assert_allclose(
        interpolate_nodal(f, nodes, cells, "quad4", np.zeros(50, int), x), n @ f, atol=1e-12)
    tri = np.array([[0, 1, 2]])
    bary = rng.dirichlet(np.ones(3), 20)
    np.testing.assert_allclose(
        interpolate_nodal(f, nodes, tri, "tri3", np.zeros(20, int), bary @ nodes[:3]), bary @ f[:3],
        atol=1e-12)


def test_pieces_of_a_step_join_into_it(tmp_path):
    """The pieces of an MPI run (rockfrac.output.vtk.piece_of): each holds its cells and the points
    they use, with node_id and cell_id back into the whole grid; together they are the whole grid,
    and the .pvtu written by write_piece declares every field with its VTK type and components."""
    whole = fields_2d(3)
    owner = [np.array([0, 1]), np.array([1]), np.array([0])]  # bulk, interface, segment: their ranks
    pieces = [piece_of(whole, [o == r for o in owner]) for r in range(2)]
    points = np.full(whole.points.shape, np.nan)
    for piece in pieces:
        points[piece.point_data["node_id"]] = piece.points
        np.testing.assert_array_equal(piece.point_data["displacement"],
                                      whole.point_data["displacement"][piece.point_data["node_id"]])
        for (kind, conn), rows in zip(piece.cells, piece.cell_data["cell_id"]):
            full = dict(whole.cells)[kind] if kind != "quad" else None
            if full is not None:
                np.testing.assert_array_equal(piece.point_data["node_id"][conn], full[rows])
    np.testing.assert_array_equal(points, whole.points)
    assert [k for k, _ in pieces[0].cells] == ["quad", "line"] and [k for k, _ in pieces[1].cells] == ["quad", "quad"]
    np.testing.assert_array_equal(pieces[1].cell_data["cell_id"][1], [0])  # the interface, its block's first
    np.testing.assert_array_equal(pieces[1].cell_data["state"][1], whole.cell_data["state"][1])
    series = [VtkSeries(tmp_path, rank=r, ranks=2) for r in range(2)]
    waited = []
    series[1].write_piece(7, 7.0, pieces[1], lambda: waited.append(1))
    series[0].write_piece(7, 7.0, pieces[0], lambda: waited.append(0))
    assert waited == [1, 0] and pvd_entries(tmp_path / "results.pvd") == [(7.0, "results_00007.pvtu")]
    root = ET.parse(tmp_path / "results_00007.pvtu").getroot()
    assert [e.get("Source") for e in root.iter("Piece")] == ["results_00007_p0.vtu", "results_00007_p1.vtu"]
    declared = {e.get("Name"): (e.get("type"), e.get("NumberOfComponents"))
                for e in root.find("PUnstructuredGrid/PCellData")}
    assert declared["cell_kind"] == ("Int8", "1") and declared["stress"] == ("Float64", "6")
    assert declared["cell_id"] == ("Int64", "1")
    back = meshio.read(tmp_path / "results_00007_p1.vtu")
    assert set(back.cell_data) == set(declared) and set(back.point_data) == {"displacement", "node_id"}
    VtkSeries(tmp_path, rank=0, ranks=2)  # a new series deletes the pieces and the .pvtu
    assert sorted(p.name for p in tmp_path.iterdir()) == ["results.pvd"]


def test_a_piece_without_a_kind_of_cell_has_every_field_of_the_whole_grid():
    """An MPI rank's piece with bulk cells only, of a grid whose other pieces hold crack segments:
    the segments' fields are there, NaN, and every field has the whole grid's dtype (a field some
    kind of cell lacks is float64 in every piece, as in the serial grid), so the pieces fit one
    .pvtu; node_id and cell_id are the given ones."""
    from rockfrac.output.fields import _as_in_the_whole_grid

    nodes = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    bulk = {"stress": np.ones((1, 6)), "region": np.array([3], dtype=np.int32)}
    piece = step_fields(nodes, np.array([[0, 1, 2, 3]]), "quad4", point_data={"displacement": np.zeros((4, 2))},
                        bulk_data=bulk)
    segments = {"jump": np.zeros((5, 2)), "state": np.zeros(5, dtype=np.int8)}
    out = _as_in_the_whole_grid(piece, [CellKind.BULK], [np.array([7])], np.array([10, 11, 12, 13]),
                                [bulk, segments])
    assert set(out.cell_data) == {"stress", "region", "jump", "state", "cell_kind", "cell_id"}
    assert out.cell_data["region"][0].dtype == np.float64 and out.cell_data["region"][0][0] == 3.0
    assert np.isnan(out.cell_data["jump"][0]).all() and out.cell_data["jump"][0].shape == (1, 2)
    assert out.cell_data["state"][0].dtype == np.float64
    assert out.cell_data["cell_kind"][0].dtype == np.int8 and out.cell_data["cell_id"][0].tolist() == [7]
    assert out.point_data["node_id"].tolist() == [10, 11, 12, 13]
    whole = step_fields(nodes, np.array([[0, 1, 2, 3]]), "quad4", point_data={"displacement": np.zeros((4, 2))},
                        bulk_data=bulk, segments=(np.zeros((5, 2)), np.ones((5, 2))), segment_data=segments)
    assert {k: v[0].dtype for k, v in whole.cell_data.items()} == \
        {k: v[0].dtype for k, v in out.cell_data.items() if k != "cell_id"}
