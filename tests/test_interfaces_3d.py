"""Cohesive surfaces in 3D meshes: insertion (node counts, connectivity, crack fronts, face sets),
nodal integration points and their frames, and unyielded surfaces on every face reproducing the
unsplit elastic solution (RP exactly, also where many interfaces meet along an edge)."""

from __future__ import annotations

import numpy as np
import pytest

from rockfrac.api import make_case, run
from rockfrac.elements.interface_points import interface_points_3d
from rockfrac.mesh import interfaces_3d as i3
from rockfrac.mesh import rock_tests as rt
from rockfrac.mesh.gmsh_io import read_mesh
from rockfrac.mesh.interfaces import tied_nodes
from rockfrac.mesh.topology import CELL_FACES, boundary_faces, on_boundary


@pytest.fixture(scope="module", params=["tet4", "hex8"])
def box(tmp_path_factory, request):
    path = rt.box(tmp_path_factory.mktemp("box") / "box.msh", (1.0, 1.0, 1.0), (2, 2, 2), element=request.param)
    return path, read_mesh(path, dim=3)


def test_every_face_split_leaves_each_cell_its_own_nodes(box):
    _, m = box
    faces = i3.internal_faces(m)
    n_corner = m.cells.shape[1]
    # internal faces: (faces of all cells - boundary faces) / 2
    assert len(faces.faces) == (len(m.cells) * len(CELL_FACES[n_corner]) - len(boundary_faces(m))) // 2
    split = i3.insert_faces(m, i3.all_faces(m))
    assert split.check() == []
    assert split.n_nodes == n_corner * len(m.cells)
    assert np.unique(split.cells).size == split.cells.size  # no node shared by two cells
    assert split.interfaces.shape == (len(faces.faces), 2 * faces.faces.shape[1])
    half = split.interfaces.shape[1] // 2
    np.testing.assert_array_equal(split.nodes[split.interfaces[:, :half]], split.nodes[split.interfaces[:, half:]])
    # the minus face's right-hand normal points into the plus cell
    owner = np.full(split.n_nodes, -1)
    owner[split.cells.ravel()] = np.repeat(np.arange(len(split.cells)), n_corner)
    x = split.nodes[split.interfaces[:, :half]]
    normal = np.cross(x[:, 1] - x[:, 0], x[:, -1] - x[:, 0])
    plus_centre = split.nodes[split.cells[owner[split.interfaces[:, half]]]].mean(axis=1)
    minus_centre = split.nodes[split.cells[owner[split.interfaces[:, 0]]]].mean(axis=1)
    face_centre = x.mean(axis=1)
    assert (np.einsum("ki,ki->k", normal, plus_centre - face_centre) > 0).all()
    assert (np.einsum("ki,ki->k", normal, minus_centre - face_centre) < 0).all()
    # tying the copies gives back the mesh; boundary face sets follow their cells' copies
    rep = tied_nodes(split)
    assert np.unique(rep).size == m.n_nodes and rep.max() < m.n_nodes
    np.testing.assert_array_equal(split.nodes, m.nodes[rep])
    for name, fs in split.face_sets.items():
        np.testing.assert_array_equal(rep[fs], m.face_sets[name])
        assert on_boundary(split, fs).all()


def test_a_crack_ending_inside_the_body_keeps_its_front_nodes_whole(box):
    """The faces in the plane x = 1/2 with y < 1/2: a crack from the front face (y = 0) to a front
    along y = 1/2 inside the body. Only its nodes off the front are split."""
    _, m = box
    f = i3.internal_faces(m)
    x = m.nodes[f.faces]
    sel = np.all(np.isclose(x[..., 0], 0.5), axis=1) & (x[..., 1].mean(axis=1) < 0.5)
    assert sel.sum() > 0
    split = i3.insert_faces(m, sel)
    on_crack = np.unique(f.faces[sel])
    behind_front = on_crack[m.nodes[on_crack, 1] < 0.5 - 1e-12]
    assert split.n_nodes == m.n_nodes + behind_front.size
    pairs = interface_points_3d(split.nodes, split.interfaces)
    assert pairs.n == behind_front.size  # the front's pairs are one node: no point
    # the points behind the front are exactly its split nodes, their normals +-x, and their weights
    # the crack's area less the front nodes' shares (0.5 m^2 in all)
    np.testing.assert_array_equal(np.sort(pairs.minus), np.sort(tied_nodes(split)[pairs.minus]))
    np.testing.assert_array_equal(np.sort(tied_nodes(split)[pairs.plus]), np.sort(behind_front))
    np.testing.assert_allclose(np.abs(pairs.frame[:, 2, 0]), 1.0, atol=1e-12)
    from rockfrac.elements.interface_points import face_rule

    shape, _, nda = face_rule(m.nodes[f.faces[sel]])
    share = np.einsum("qa,kq->ka", shape, np.linalg.norm(nda, axis=2))  # int N_a dA per face node
    assert share.sum() == pytest.approx(0.5, rel=1e-12)
    behind = m.nodes[f.faces[sel], 1] < 0.5 - 1e-12
    assert pairs.weight.sum() == pytest.approx(share[behind].sum(), rel=1e-12)


def test_interface_points_weights_frames_and_consistent_tractions(box):
    _, m = box
    split = i3.insert_faces(m, i3.all_faces(m))
    pts = interface_points_3d(split.nodes, split.interfaces)
    # the three internal planes x, y, z = 1/2 of the unit box: total area 3, each node's weight its
    # share; every point's frame orthonormal and right-handed with n the face normal
    assert len(pts.minus) == pts.n
    r = pts.frame
    np.testing.assert_allclose(np.einsum("pij,pkj->pik", r, r), np.broadcast_to(np.eye(3), r.shape), atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(r), 1.0, atol=1e-12)
    steep = np.abs(r[:, 2, 2]) < 0.99  # t1 along the strike (horizontal) where n is not vertical
    assert steep.sum() > 0 and np.abs(r[steep, 0, 2]).max() < 1e-12
    f = i3.internal_faces(m)
    xf = m.nodes[f.faces]
    area = np.linalg.norm(np.cross(xf[:, 1] - xf[:, 0], xf[:, -1] - xf[:, 0]), axis=1).sum()
    if f.faces.shape[1] == 3:
        area *= 0.5
    assert pts.weight.sum() == pytest.approx(area, rel=1e-12)
    sig = np.array([-1e6, -2e6, -3e6, 5e5, 2e5, 1e5])
    full = sig[[0, 3, 5, 3, 1, 4, 5, 4, 2]].reshape(3, 3)
    t = pts.consistent_tractions(lambda x: np.tile(sig, (len(x), 1)))
    np.testing.assert_allclose(t, pts.frame[:, 2] @ full, atol=1e-9 * 3e6)


@pytest.mark.parametrize("form,tol", [("rp", 1e-9), ("ep", 1e-4)])
def test_unyielded_surfaces_on_every_face_reproduce_the_unsplit_solution(box, tmp_path, form, tol):
    """Surfaces on every internal face (edges where 4 or 6 of them meet), too strong to yield, under a
    traction, a pressure and a fixed base: the RP form gives the unsplit displacements exactly (to
    the junction regularisation's 1e-13 m), the EP form within its penalty compliance."""
    path, m = box
    stages = [{"name": "load", "displacement": {"bottom": {"x": 0.0, "y": 0.0, "z": 0.0}},
               "traction": {"top": [1e6, -2e6, -5e5]}, "pressure": {"right": 3e5}}]
    base = dict(mesh={"kind": "gmsh", "file": str(path)}, bulk={"E": 2e10, "nu": 0.25}, stages=stages,
                output={"picture": False})
    plain = run(make_case(**base), tmp_path / "plain")
    coh = {"where": "all", "form": form, "law": "bilinear", "sigma_c": 1e9, "Gc": 1e3, "beta": 1.0,
           **({"augmentation": 1e13} if form == "rp" else {"kn": 1e16, "kt": 1e16})}
    split = run(make_case(**base, cohesive=coh), tmp_path / "split")
    rep = tied_nodes(split.built.mesh)
    u, u0 = split.displacement(), plain.displacement()
    err = np.abs(u - u0[rep]).max() / np.abs(u0).max()
    assert err < tol
    if form == "ep":
        assert err > 1e-9  # the penalty's compliance is there, not a tied mesh
    h = split.history
    assert h["n_plastic"][-1] == 0 and h["newton_iterations"][-1] <= 2
    for comp in "xyz":
        assert h[f"R_bottom_{comp}"][-1] == pytest.approx(plain.history[f"R_bottom_{comp}"][-1], rel=1e-6, abs=1e-3)


def test_drive_takes_3d_jump_paths_and_reduces_to_2d(tmp_path):
    """``rockfrac drive`` with columns jump_t1, jump_t2, jump_n: along t2 = 0 the 2D law's numbers; a
    path rotated about n gives the rotated tangential traction and the same normal one."""
    from pathlib import Path

    from rockfrac.cli import main
    from rockfrac.output.csvout import read_csv

    law = Path(__file__).resolve().parents[1] / "examples" / "laws" / "cse_law.toml"
    t = np.linspace(0.0, 2e-4, 41)
    jn = np.linspace(0.0, 2e-5, 41)
    (tmp_path / "p2.csv").write_text("jump_t,jump_n\n" + "".join(f"{float(a)!r},{float(b)!r}\n" for a, b in zip(t, jn)))
    c, s = np.cos(0.7), np.sin(0.7)
    (tmp_path / "p3.csv").write_text("jump_t1,jump_t2,jump_n\n" + "".join(
        f"{float(c * a)!r},{float(s * a)!r},{float(b)!r}\n" for a, b in zip(t, jn)))
    assert main(["drive", str(law), "--path", str(tmp_path / "p2.csv"), "--out", str(tmp_path / "d2")]) == 0
    assert main(["drive", str(law), "--path", str(tmp_path / "p3.csv"), "--out", str(tmp_path / "d3")]) == 0
    d2, d3 = read_csv(tmp_path / "d2" / "drive.csv"), read_csv(tmp_path / "d3" / "drive.csv")
    scale = np.abs(d2["T_t"]).max()
    assert scale > 1e3 and d2["eps_s_p"][-1] > 0  # it slid plastically
    np.testing.assert_allclose(d3["T_t1"], c * np.asarray(d2["T_t"]), rtol=1e-9, atol=1e-9 * scale)
    np.testing.assert_allclose(d3["T_t2"], s * np.asarray(d2["T_t"]), rtol=1e-9, atol=1e-9 * scale)
    np.testing.assert_allclose(d3["T_n"], d2["T_n"], rtol=1e-9, atol=1e-9 * scale)
    np.testing.assert_allclose(d3["c"], d2["c"], rtol=1e-12)


def test_grain_aggregate_boundaries_split_every_grain_off(tmp_path):
    """rockfrac.mesh.aggregate: Voronoi grains of a tetrahedral box; where = 'boundaries' selects
    exactly the faces between two grains, and splitting them leaves no node shared by two grains
    while each grain's cells stay joined where they share a face (a grain resolved on the mesh may
    touch itself only along an edge: that joint is cut, as the insertion rule says)."""
    import scipy.sparse as sp
    from scipy.sparse.csgraph import connected_components

    from rockfrac.mesh.aggregate import grain_box
    from rockfrac.mesh.interfaces import region_labels

    m = read_mesh(grain_box(tmp_path / "g.msh", (0.05, 0.05, 0.1), (4, 4, 8), n_grains=6, seed=3), dim=3)
    assert m.cell_type == "tet4" and m.check() == [] and len(m.regions) == 6
    assert sum(len(v) for v in m.regions.values()) == len(m.cells) == 6 * 4 * 4 * 8
    for name in ("left", "right", "front", "back", "bottom", "top"):
        assert on_boundary(m, m.face_sets[name]).all()
    label = region_labels(m)
    sel = i3.faces_on_region_boundaries(m)
    f = i3.internal_faces(m)
    assert sel.sum() > 0 and np.all(label[f.cells[sel, 0]] != label[f.cells[sel, 1]])
    assert np.all(label[f.cells[~sel, 0]] == label[f.cells[~sel, 1]])
    split = i3.insert_faces(m, sel)
    owner = np.full(split.n_nodes, -1)
    for g in range(6):
        nodes = np.unique(split.cells[label == g])
        assert np.all(owner[nodes] == -1)  # no node of another grain
        owner[nodes] = g
        # the grain's pieces after the split (cells sharing a node) are its face-connected pieces
        cells = np.flatnonzero(label == g)
        inc = sp.csr_matrix((np.ones(cells.size * 4), (np.repeat(np.arange(cells.size), 4),
                                                        split.cells[cells].ravel())), shape=(cells.size, split.n_nodes))
        inside = (label[f.cells[:, 0]] == g) & (label[f.cells[:, 1]] == g)
        local = np.full(len(m.cells), -1)
        local[cells] = np.arange(cells.size)
        pairs = local[f.cells[inside]]
        faces_graph = sp.coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(cells.size,) * 2)
        assert (connected_components(inc @ inc.T, directed=False)[0]
                == connected_components(faces_graph, directed=False)[0])


def test_boundaries_in_2d_are_the_edges_between_regions(tmp_path):
    """where = 'boundaries' on the 2D grains specimen is where = 'between' its two regions."""
    from rockfrac.mesh import interfaces as itf
    from rockfrac.mesh.grains import block_with_inclusion

    m = block_with_inclusion(0.04, 0.08, 8, 16, (0.01, 0.02, 0.03, 0.05))
    sel = itf.edges_on_region_boundaries(m)
    assert sel.sum() == 2 * (4 + 6)  # the inclusion's perimeter: 4 + 6 cells a side
    np.testing.assert_array_equal(sel, itf.edges_between(m, "weak", "bulk"))
