"""Reading Gmsh meshes: groups, orientation of cells and boundary edges, and the error messages."""

import gmsh
import numpy as np
import pytest

from rockfrac.case.schema import CaseError
from rockfrac.mesh.gmsh_io import (
    boundary_edges,
    boundary_faces,
    gmsh_session,
    on_boundary,
    read_mesh,
    require_groups,
)

W, H = 2.0, 1.0
SIDES = {"bottom": (0.0, -1.0), "right": (1.0, 0.0), "top": (0.0, 1.0), "left": (-1.0, 0.0)}


def two_layer_msh(path, *, quads=False, mixed=False, version=4.1, save_all=0, skip_upper=False,
                  interface=False, order=1, alias=False):
    """A W x H rectangle of two surfaces (lower, upper) with boundary curves and bottom_left."""
    with gmsh_session("test"):
        occ = gmsh.model.occ
        lower, upper = occ.addRectangle(0, 0, 0, W, H / 2), occ.addRectangle(0, H / 2, 0, W, H / 2)
        occ.fragment([(2, lower)], [(2, upper)])
        occ.synchronize()
        gmsh.model.addPhysicalGroup(2, [lower], name="lower")
        if not skip_upper:
            gmsh.model.addPhysicalGroup(2, [upper], name="upper")
        e = 1e-6
        for name, box in {"bottom": (-e, -e, W + e, e), "top": (-e, H - e, W + e, H + e),
                          "left": (-e, -e, e, H + e), "right": (W - e, -e, W + e, H + e),
                          "interface": (-e, H / 2 - e, W + e, H / 2 + e)}.items():
            if name == "interface" and not interface:
                continue
            x0, y0, x1, y1 = box
            found = gmsh.model.getEntitiesInBoundingBox(x0, y0, -e, x1, y1, e, dim=1)
            curves = [t for _, t in found]
            gmsh.model.addPhysicalGroup(1, curves, name=name)
            if alias and name == "bottom":  # the same curve in a second group
                gmsh.model.addPhysicalGroup(1, curves, name="base")
        gmsh.model.addPhysicalGroup(0, [t for _, t in gmsh.model.getEntitiesInBoundingBox(
            -e, -e, -e, e, e, e, dim=0)], name="bottom_left")
        gmsh.option.setNumber("Mesh.MeshSizeMax", 0.3)
        if quads:
            gmsh.option.setNumber("Mesh.RecombineAll", 1)
        if mixed:
            gmsh.model.mesh.setRecombine(2, upper)
        gmsh.option.setNumber("Mesh.SaveAll", save_all)
        gmsh.option.setNumber("Mesh.MshFileVersion", version)
        gmsh.model.mesh.generate(2)
        if order > 1:
            gmsh.model.mesh.setOrder(order)
        gmsh.write(str(path))
    return path


def msh22(path, nodes, elements, names=()):
    """A hand-written MSH 2.2 file: nodes (x, y[, z]); elements (gmsh type, physical, node ids
    from 1); names (dim, physical, name)."""
    lines = ["$MeshFormat", "2.2 0 8", "$EndMeshFormat", "$PhysicalNames", str(len(names))]
    lines += [f'{d} {t} "{n}"' for d, t, n in names]
    lines += ["$EndPhysicalNames", "$Nodes", str(len(nodes))]
    lines += [f"{i + 1} {x[0]} {x[1]} {x[2] if len(x) > 2 else 0.0}" for i, x in enumerate(nodes)]
    lines += ["$EndNodes", "$Elements", str(len(elements))]
    lines += [f"{i + 1} {t} 2 {p} {p} {' '.join(map(str, ids))}"
              for i, (t, p, ids) in enumerate(elements)]
    lines += ["$EndElements"]
    path.write_text("\n".join(lines) + "\n")
    return path


def polygon_areas(mesh, cells):
    x = mesh.nodes[mesh.cells[cells]]
    x1 = np.roll(x, -1, axis=1)
    return 0.5 * (x[..., 0] * x1[..., 1] - x1[..., 0] * x[..., 1]).sum(axis=1)


@pytest.mark.parametrize("quads,version", [(False, 4.1), (True, 4.1), (False, 2.2)])
def test_round_trip_groups_and_orientation(tmp_path, quads, version):
    mesh = read_mesh(two_layer_msh(tmp_path / "two.msh", quads=quads, version=version, alias=True))
    assert np.array_equal(mesh.edge_sets.pop("base"), mesh.edge_sets["bottom"])  # MSH 2: no repeats
    assert np.array_equal(mesh.node_sets.pop("base"), mesh.node_sets["bottom"])
    assert mesh.cell_type == ("quad4" if quads else "tri3")
    assert mesh.check() == []
    assert np.array_equal(np.unique(mesh.cells), np.arange(mesh.n_nodes))  # no unused nodes
    assert set(mesh.regions) == {"lower", "upper"}
    lower, upper = mesh.regions["lower"], mesh.regions["upper"]
    assert len(lower) + len(upper) == len(mesh.cells) and not set(lower) & set(upper)
    areas = polygon_areas(mesh, np.arange(len(mesh.cells)))
    assert np.all(areas > 0)  # counter-clockwise
    assert areas[lower].sum() == pytest.approx(W * H / 2)
    assert areas[upper].sum() == pytest.approx(W * H / 2)
    # node sets: every node of a side, and the corner
    x, y = mesh.nodes.T
    for name, on in {"bottom": np.isclose(y, 0), "top": np.isclose(y, H), "left": np.isclose(x, 0),
                     "right": np.isclose(x, W)}.items():
        assert np.array_equal(mesh.node_sets[name], np.flatnonzero(on))
    assert np.allclose(mesh.nodes[mesh.node_sets["bottom_left"]], [[0.0, 0.0]])
    # edge sets: counter-clockwise, outward normals (dy, -dx)/L, closed
    total = np.zeros(2)
    for name, normal in SIDES.items():
        d = mesh.nodes[mesh.edge_sets[name][:, 1]] - mesh.nodes[mesh.edge_sets[name][:, 0]]
        length = np.linalg.norm(d, axis=1)
        assert np.allclose(np.column_stack([d[:, 1], -d[:, 0]]) / length[:, None], normal)
        total += np.column_stack([d[:, 1], -d[:, 0]]).sum(axis=0)
        assert length.sum() == pytest.approx(W if name in ("bottom", "top") else H)
    assert np.allclose(total, 0.0, atol=1e-12)
    sides = np.vstack([mesh.edge_sets[n] for n in SIDES])
    assert {tuple(e) for e in sides} == {tuple(e) for e in boundary_edges(mesh)}


def test_internal_curve_kept_and_not_on_boundary(tmp_path):
    mesh = read_mesh(two_layer_msh(tmp_path / "two.msh", interface=True))
    inner = mesh.edge_sets["interface"]
    assert len(inner) > 0 and not on_boundary(mesh, inner).any()
    assert on_boundary(mesh, mesh.edge_sets["left"]).all()
    assert np.allclose(mesh.nodes[inner][:, :, 1], H / 2)


def test_clockwise_cells_are_reversed(tmp_path):
    nodes = [(0, 0), (1, 0), (1, 1), (0, 1), (2, 0), (2, 1)]
    # one clockwise quad, one counter-clockwise quad, one clockwise line on the bottom
    elements = [(3, 1, (1, 4, 3, 2)), (3, 1, (2, 5, 6, 3)), (1, 2, (2, 1))]
    path = msh22(tmp_path / "cw.msh", nodes, elements, [(2, 1, "rock"), (1, 2, "bottom")])
    mesh = read_mesh(path)
    assert mesh.check() == [] and np.all(polygon_areas(mesh, [0, 1]) > 0)
    x = mesh.nodes[mesh.edge_sets["bottom"]]  # (1 edge, 2 ends, xy)
    assert np.allclose(x[:, 1] - x[:, 0], [1.0, 0.0])  # turned counter-clockwise


def test_hex_faces_outward(tmp_path):
    path = tmp_path / "box.msh"
    with gmsh_session("box"):
        gmsh.model.occ.addRectangle(0, 0, 0, 1, 1)
        gmsh.model.occ.extrude([(2, 1)], 0, 0, 1, numElements=[2], recombine=True)
        gmsh.model.occ.synchronize()
        for c in range(1, 5):
            gmsh.model.mesh.setTransfiniteCurve(c, 3)
        gmsh.model.mesh.setTransfiniteSurface(1)
        gmsh.model.mesh.setRecombine(2, 1)
        gmsh.model.addPhysicalGroup(3, [1], name="rock")
        e = 1e-6
        for name, x0 in (("left", 0.0), ("right", 1.0)):
            found = gmsh.model.getEntitiesInBoundingBox(x0 - e, -e, -e, x0 + e, 1 + e, 1 + e, 2)
            faces = [t for _, t in found]
            gmsh.model.addPhysicalGroup(2, faces, name=name)
        gmsh.model.mesh.generate(3)
        gmsh.write(str(path))
    mesh = read_mesh(path, dim=3)
    assert mesh.cell_type == "hex8" and mesh.check() == [] and len(mesh.cells) == 8
    for name, nx in (("left", -1.0), ("right", 1.0)):
        x = mesh.nodes[mesh.face_sets[name]]
        n = np.cross(x[:, 1] - x[:, 0], x[:, 3] - x[:, 0])
        assert len(n) == 4 and np.all(n[:, 0] * nx > 0)
    assert len(boundary_faces(mesh)) == 24
    assert read_mesh(path, dim=None).cell_type == "hex8"  # the file's own dimension
    with pytest.raises(CaseError, match=r"box\.msh: the mesh has 3D elements but a 2D mesh was"):
        read_mesh(path)


def test_require_groups_lists_the_groups(tmp_path):
    mesh = read_mesh(two_layer_msh(tmp_path / "grains.msh"))
    require_groups(mesh, ["lower", "top", "bottom_left"], "grains.msh")
    with pytest.raises(CaseError) as err:
        require_groups(mesh, ["top", "crack"], "grains.msh")
    assert str(err.value) == (
        "grains.msh: physical group 'crack' not found; groups in the file: regions 'lower', "
        "'upper'; edge sets 'bottom', 'left', 'right', 'top'; node sets 'bottom', 'bottom_left', "
        "'left', 'right', 'top'")
    with pytest.raises(CaseError, match=r"physical group 'lower' not found as an edge set"):
        require_groups(mesh, ["lower"], "grains.msh", kind="edge_sets")


def test_mixed_cell_types(tmp_path):
    with pytest.raises(CaseError) as err:
        read_mesh(two_layer_msh(tmp_path / "mixed.msh", mixed=True))
    msg = str(err.value)
    assert msg.startswith(f"{tmp_path / 'mixed.msh'}: the 2D cells must all be of one type, tri3 "
                          "('Triangle 3') or quad4 ('Quadrilateral 4'); found ")
    assert "x 'Triangle 3'" in msg and "x 'Quadrilateral 4'" in msg


def test_unsupported_cell_type(tmp_path):
    with pytest.raises(CaseError, match=r"must all be of one type, .*; found \d+ x 'Triangle 6'"):
        read_mesh(two_layer_msh(tmp_path / "p2.msh", order=2))


def test_inverted_cell(tmp_path):
    nodes = [(0, 0), (1, 0), (0, 1), (1, 1)]
    path = msh22(tmp_path / "bowtie.msh", nodes, [(3, 1, (1, 2, 3, 4))], [(2, 1, "rock")])
    expected = (r"bowtie.msh: 1 degenerate or inverted cells \(zero or mixed-sign Jacobian within "
                r"the cell\): element 1 at \(0.5, 0.5\)")
    with pytest.raises(CaseError, match=expected):
        read_mesh(path)


def test_missing_file(tmp_path):
    with pytest.raises(CaseError, match=r"nope\.msh: no such file"):
        read_mesh(tmp_path / "nope.msh")


def test_not_a_mesh(tmp_path):
    path = tmp_path / "junk.msh"
    path.write_text("hello\n")
    with pytest.raises(CaseError, match=r"junk\.msh: not a Gmsh mesh file"):
        read_mesh(path)


def test_cell_outside_every_region(tmp_path):
    expected = (r"orphan.msh: \d+ of \d+ cells .* belong to no physical surface; every cell needs "
                r"a region \(material\): add surfaces \[2\]")
    with pytest.raises(CaseError, match=expected):
        read_mesh(two_layer_msh(tmp_path / "orphan.msh", skip_upper=True, save_all=1))
    # Gmsh's default (Mesh.SaveAll = 0) drops those cells: the boundary curves then hang free
    with pytest.raises(CaseError, match=r"physical curve '(top|left|right)' has \d+ nodes on no"):
        read_mesh(two_layer_msh(tmp_path / "hole.msh", skip_upper=True))


def test_no_physical_surface_gives_one_bulk_region(tmp_path):
    path = msh22(tmp_path / "plain.msh", [(0, 0), (1, 0), (0, 1), (9, 9)], [(2, 0, (1, 2, 3))])
    mesh = read_mesh(path)
    assert set(mesh.regions) == {"bulk"} and mesh.n_nodes == 3 and mesh.cell_type == "tri3"


def test_2d_mesh_must_be_planar(tmp_path):
    path = msh22(tmp_path / "warped.msh", [(0, 0, 0), (1, 0, 0), (0, 1, 0.5)], [(2, 1, (1, 2, 3))])
    with pytest.raises(CaseError, match=r"warped.msh: a 2D mesh must lie in a plane z = const"):
        read_mesh(path)


def test_session_keeps_the_callers_model():
    gmsh.initialize(readConfigFiles=False, interruptible=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add("mine")
        gmsh.model.occ.addBox(0, 0, 0, 1, 1, 1)
        gmsh.model.occ.synchronize()
        with gmsh_session("inner"):
            gmsh.model.occ.addDisk(0, 0, 0, 1, 1)
        assert gmsh.model.getCurrent() == "mine" and gmsh.model.getEntities(3) == [(3, 1)]
    finally:
        gmsh.finalize()


def test_mirrored_hexahedron_is_reversed(tmp_path):
    cube = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)]
    # bottom face clockwise seen from above: a mirrored hexahedron
    path = msh22(tmp_path / "hex.msh", cube, [(5, 1, (1, 4, 3, 2, 5, 8, 7, 6))], [(3, 1, "rock")])
    mesh = read_mesh(path, dim=3)
    assert mesh.check() == [] and np.array_equal(mesh.cells, [[0, 1, 2, 3, 4, 5, 6, 7]])
