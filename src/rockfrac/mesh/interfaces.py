"""Cohesive-surface insertion: split a 2D mesh along chosen internal edges.

Edges are numbered once by :func:`internal_edges`; a selection is a boolean mask over that
numbering (combine selections with ``&``, ``|``, ``~``). :func:`insert_interfaces` duplicates the
nodes on the selected edges and returns a new :class:`Mesh` with one interface cell
``(m0, m1, p0, p1)`` per selected edge.

How nodes are split. For every node on a selected edge, its incident cells are grouped into fans:
two cells are connected when they share an edge through the node that is not selected. The fan
holding the lowest-numbered cell keeps the node's index; every other fan gets a copy, numbered
after the existing nodes (grouped by original node). So a crack tip (one fan) is not split, a
crack running into the boundary splits the boundary node (an open fan cut in two), and a junction
of k selected edges around an interior node gives k copies. Everything is vectorized: the fans are
the connected components of a graph over the (cell, corner) incidences (scipy.sparse.csgraph).

Example::

    sel = edges_between(mesh, "rock", "vein")
    cracked = insert_interfaces(mesh, sel, minus_side(mesh, sel, "rock"))
"""

from __future__ import annotations

from dataclasses import replace
from typing import NamedTuple

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from rockfrac.mesh.mesh import Mesh

Region = str | np.ndarray  # a region name, cell indices, or a boolean mask over the cells


class InternalEdges(NamedTuple):
    """Edges shared by two bulk cells: edges (k, 2) node pairs, oriented counter-clockwise around
    cells[:, 0]; cells (k, 2) the two cells (lower index first); local (k, 2) the edge's local
    index in each (local edge j joins corners j and j + 1)."""

    edges: np.ndarray
    cells: np.ndarray
    local: np.ndarray


def _cell_edges(cells: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Directed local edges of every cell: tails and heads, each (n_cells, n_vertices)."""
    return cells, np.roll(cells, -1, axis=1)


def internal_edges(mesh: Mesh) -> InternalEdges:
    """Every edge shared by two bulk cells (tri3 or quad4), found by sorting node-pair keys.

    Raises ValueError for a 3D mesh or an edge shared by more than two cells.
    """
    if mesh.dim != 2:
        raise ValueError(f"interfaces are 2D only; this mesh is {mesh.dim}D ({mesh.cell_type})")
    cells = mesh.cells
    nc, nv = cells.shape
    tail, head = _cell_edges(cells)
    n = np.int64(max(mesh.n_nodes, 1))
    key = (np.minimum(tail, head) * n + np.maximum(tail, head)).ravel()  # (nc nv,)
    order = np.argsort(key, kind="stable")  # equal keys: lower cell first
    k = key[order]
    same = k[1:] == k[:-1]
    if np.any(same[1:] & same[:-1]):
        raise ValueError("an edge is shared by more than two cells (non-manifold mesh)")
    first = order[:-1][same]  # flat (cell, local) index in the first cell
    second = order[1:][same]
    pair_cells = np.stack([first // nv, second // nv], axis=1)
    pair_local = np.stack([first % nv, second % nv], axis=1)
    edges = np.stack([tail.ravel()[first], head.ravel()[first]], axis=1)
    return InternalEdges(edges, pair_cells, pair_local)


# -- selections: boolean masks over internal_edges(mesh) --------------------------------------


def _region_mask(mesh: Mesh, region: Region) -> np.ndarray:
    """Boolean mask over the cells of a region given by name, cell indices or a mask."""
    if isinstance(region, str):
        if region not in mesh.regions:
            raise KeyError(f"no region {region!r}; known: {sorted(mesh.regions)}")
        region = mesh.regions[region]
    region = np.asarray(region)
    if region.dtype == bool:
        if region.shape != (mesh.cells.shape[0],):
            raise ValueError("a boolean region mask needs one entry per cell")
        return region
    mask = np.zeros(mesh.cells.shape[0], dtype=bool)
    mask[region.astype(np.int64)] = True
    return mask


def region_labels(mesh: Mesh) -> np.ndarray:
    """A label per cell (n_cells,): the index of its first region in ``mesh.regions`` (-1: none)."""
    label = np.full(mesh.cells.shape[0], -1, dtype=np.int64)
    for k, cells in reversed(list(enumerate(mesh.regions.values()))):
        label[np.asarray(cells, dtype=np.int64)] = k
    return label


def edges_on_region_boundaries(mesh: Mesh) -> np.ndarray:
    """Internal edges whose two cells lie in different regions (every grain boundary at once)."""
    label = region_labels(mesh)
    c = internal_edges(mesh).cells
    return label[c[:, 0]] != label[c[:, 1]]


def all_edges(mesh: Mesh) -> np.ndarray:
    """Every internal edge (a fully fragmentable mesh)."""
    return np.ones(internal_edges(mesh).edges.shape[0], dtype=bool)


def edges_within(mesh: Mesh, region: Region) -> np.ndarray:
    """Internal edges whose two cells both lie in ``region`` (every internal edge of a region)."""
    inside = _region_mask(mesh, region)
    return inside[internal_edges(mesh).cells].all(axis=1)


def edges_between(mesh: Mesh, region_a: Region, region_b: Region) -> np.ndarray:
    """Internal edges with one cell in ``region_a`` and the other in ``region_b``.

    To put region_a on the minus side (normals from a into b), pass
    ``minus_side(mesh, selected, region_a)`` as ``minus_cells`` to :func:`insert_interfaces`.
    """
    a, b = _region_mask(mesh, region_a), _region_mask(mesh, region_b)
    c = internal_edges(mesh).cells
    return (a[c[:, 0]] & b[c[:, 1]]) | (a[c[:, 1]] & b[c[:, 0]])


def edges_on(mesh: Mesh, node_pairs: np.ndarray) -> np.ndarray:
    """Internal edges joining two consecutive nodes of ``node_pairs``, in either direction.

    node_pairs: (k, 2) node pairs (e.g. a physical curve's edge set) or a (k,) polyline of nodes.
    """
    pairs = np.asarray(node_pairs, dtype=np.int64)
    if pairs.ndim == 1:
        pairs = np.stack([pairs[:-1], pairs[1:]], axis=1)
    n = np.int64(max(mesh.n_nodes, 1))
    wanted = pairs.min(axis=1) * n + pairs.max(axis=1)
    e = internal_edges(mesh).edges
    return np.isin(e.min(axis=1) * n + e.max(axis=1), wanted)


def _selected_indices(selected: np.ndarray, k: int) -> np.ndarray:
    sel = np.asarray(selected)
    if sel.dtype == bool:
        if sel.shape != (k,):
            raise ValueError(f"a selection mask needs one entry per internal edge ({k}), "
                             f"got shape {sel.shape}")
        return np.flatnonzero(sel)
    sel = sel.astype(np.int64).ravel()
    if sel.size and (sel.min() < 0 or sel.max() >= k):
        raise ValueError(f"selected edge indices must lie in 0..{k - 1}")
    if np.unique(sel).size != sel.size:
        raise ValueError("selected edge indices repeat")
    return sel


def minus_side(mesh: Mesh, selected: np.ndarray, region: Region) -> np.ndarray:
    """Minus cell of each selected edge: its cell in ``region`` (the first cell if both or neither
    lie in it). The result is the ``minus_cells`` argument of :func:`insert_interfaces`."""
    ie = internal_edges(mesh)
    c = ie.cells[_selected_indices(selected, ie.edges.shape[0])]
    inside = _region_mask(mesh, region)[c]
    return np.where(inside[:, 1] & ~inside[:, 0], c[:, 1], c[:, 0])


# -- splitting ---------------------------------------------------------------------------------


def _fans(cells: np.ndarray, ie: InternalEdges, keep: np.ndarray) -> np.ndarray:
    """Component label per (cell, corner) incidence, flat (n_cells n_vertices,); two incidences
    of a node are joined across every internal edge in ``keep`` (the edges not selected)."""
    nc, nv = cells.shape
    c0, c1 = ie.cells[keep, 0], ie.cells[keep, 1]
    l0, l1 = ie.local[keep, 0], ie.local[keep, 1]
    a = cells[c0, l0]  # the edge is a -> b in c0 (corners l0, l0 + 1)
    a_at_l1 = cells[c1, l1] == a  # in c1 it is b -> a when both cells are counter-clockwise
    ja = np.where(a_at_l1, l1, (l1 + 1) % nv)
    jb = np.where(a_at_l1, (l1 + 1) % nv, l1)
    rows = np.concatenate([c0 * nv + l0, c0 * nv + (l0 + 1) % nv])
    cols = np.concatenate([c1 * nv + ja, c1 * nv + jb])
    graph = sp.coo_matrix((np.ones(rows.size, dtype=np.int8), (rows, cols)), shape=(nc * nv,) * 2)
    return connected_components(graph, directed=False)[1]


def _split_nodes(cells: np.ndarray, labels: np.ndarray, cut: np.ndarray, n: int):
    """New cell connectivity and the parent (original node) of every new node, (n_new,)."""
    flat = cells.ravel()
    idx = np.flatnonzero(cut[flat])  # incidences of cut nodes, in cell order
    comps, first, inverse = np.unique(labels[idx], return_index=True, return_inverse=True)
    comp_node = flat[idx[first]]
    order = np.lexsort((idx[first], comp_node))  # by node, then by the fan's lowest cell
    sorted_node = comp_node[order]
    starts = np.flatnonzero(np.r_[True, sorted_node[1:] != sorted_node[:-1]])
    rank = np.arange(order.size) - np.repeat(starts, np.diff(np.r_[starts, order.size]))
    is_copy = rank > 0
    new_sorted = sorted_node.copy()
    new_sorted[is_copy] = n + np.arange(int(is_copy.sum()))
    new_of_comp = np.empty(comps.size, dtype=np.int64)
    new_of_comp[order] = new_sorted
    new_flat = flat.copy()
    new_flat[idx] = new_of_comp[inverse.ravel()]
    parent = np.concatenate([np.arange(n), sorted_node[is_copy]])
    return new_flat.reshape(cells.shape), parent


def minus_and_plus(pair: np.ndarray, local: np.ndarray, minus_cells: np.ndarray | None,
                   side: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The minus cell, plus cell and the side's local index in the minus cell of each selected side
    (an edge or a face) whose two cells are ``pair`` (k, 2), local indices ``local`` (k, 2);
    minus_cells: the wanted minus cells (default: the first of each pair)."""
    if minus_cells is None:
        flip = np.zeros(pair.shape[0], dtype=bool)
    else:
        minus_cells = np.asarray(minus_cells, dtype=np.int64).ravel()
        if minus_cells.shape != (pair.shape[0],):
            raise ValueError(f"minus_cells needs one cell per selected {side} ({pair.shape[0]})")
        flip = minus_cells == pair[:, 1]
        if np.any(~flip & (minus_cells != pair[:, 0])):
            raise ValueError(f"a minus cell is not one of the two cells of its {side}")
    mc, pc = np.where(flip, pair[:, 1], pair[:, 0]), np.where(flip, pair[:, 0], pair[:, 1])
    return mc, pc, np.where(flip, local[:, 1], local[:, 0])


def split_cut_nodes(cells: np.ndarray, labels: np.ndarray, sides: np.ndarray, n: int):
    """New connectivity, the parent of every new node and the mask (n,) of the split nodes, for the
    fan labels of the incidences and the selected sides' nodes ``sides`` (k, m)."""
    cut = np.zeros(n, dtype=bool)
    cut[sides.ravel()] = True
    new_cells, parent = _split_nodes(cells, labels, cut, n)
    split = np.zeros(n, dtype=bool)
    split[parent[n:]] = True
    return new_cells, parent, split


def copied_node_sets(node_sets: dict[str, np.ndarray], parent: np.ndarray, n: int) -> dict[str, np.ndarray]:
    """Node sets with the copies (nodes n.. with a parent in the set) of their nodes appended."""
    in_parent = np.zeros(n, dtype=bool)
    out = {}
    for name, ids in node_sets.items():
        in_parent[:] = False
        in_parent[ids] = True
        out[name] = np.concatenate([ids, n + np.flatnonzero(in_parent[parent[n:]])])
    return out


def _follow_edges(old: np.ndarray, new: np.ndarray, pairs: np.ndarray, n: int,
                  split: np.ndarray) -> np.ndarray:
    """Renumber edges (k, 2) a -> b with the copies of the cell on their left (the cell with
    a -> b counter-clockwise), else of the cell holding b -> a; direction is kept."""
    if pairs.size == 0:
        return pairs.copy()
    nv = old.shape[1]
    tail, head = _cell_edges(old)
    dkey = (tail * np.int64(n) + head).ravel()
    order = np.argsort(dkey)
    sorted_keys = dkey[order]
    out = pairs.copy()
    found = np.zeros(pairs.shape[0], dtype=bool)
    for reverse in (False, True):
        a, b = (pairs[:, 1], pairs[:, 0]) if reverse else (pairs[:, 0], pairs[:, 1])
        q = a * np.int64(n) + b
        pos = np.minimum(np.searchsorted(sorted_keys, q), sorted_keys.size - 1)
        hit = (sorted_keys[pos] == q) & ~found
        flat = order[pos[hit]]
        c, j = flat // nv, flat % nv
        na, nb = new[c, j], new[c, (j + 1) % nv]
        out[hit] = np.stack([nb, na], axis=1) if reverse else np.stack([na, nb], axis=1)
        found |= hit
    if np.any(~found & split[pairs].any(axis=1)):
        raise ValueError("an edge of an edge set or an existing interface on a split node is not "
                         "an edge of any cell; cannot tell which copy it follows")
    return out


def insert_interfaces(
    mesh: Mesh, selected: np.ndarray, minus_cells: np.ndarray | None = None
) -> Mesh:
    """Split ``mesh`` along the selected internal edges; return a new Mesh with the interfaces.

    selected: boolean mask over :func:`internal_edges` (or their indices). minus_cells: the minus
    cell of each selected edge (default: the first cell of the pair, ``internal_edges(...).cells[:,
    0]``). Each interface cell (m0, m1, p0, p1) takes m0, m1 from the minus cell, ordered so that
    the minus cell lies on the right of m0 -> m1 (the normal n = (-t_y, t_x) points into the plus
    cell), and p0, p1 from the plus cell facing them. At a crack tip the node is not split, so the
    tip's interface cell has m1 == p1 (or m0 == p0): a pair whose jump is zero by construction.

    New interfaces are appended to the existing ones, which are renumbered to follow their cells.
    Node sets gain the copies of their nodes; edge sets follow the copy of their cell (the cell on
    their left, so counter-clockwise boundary edges stay so); regions and cell indices are kept.
    """
    ie = internal_edges(mesh)
    s = _selected_indices(selected, ie.edges.shape[0])
    cells, n = mesh.cells, mesh.n_nodes
    pair, local = ie.cells[s], ie.local[s]
    mc, pc, lm = minus_and_plus(pair, local, minus_cells, "edge")
    keep = np.ones(ie.edges.shape[0], dtype=bool)
    keep[s] = False
    new_cells, parent, split = split_cut_nodes(cells, _fans(cells, ie, keep), ie.edges[s], n)

    # the minus cell is counter-clockwise: its edge lm runs a -> b with the cell on its left,
    # so m0 -> m1 = b -> a puts it on the right
    nv = cells.shape[1]
    b_corner, a_corner = (lm + 1) % nv, lm
    m0, m1 = new_cells[mc, b_corner], new_cells[mc, a_corner]
    plus_old = cells[pc]  # (k, nv)
    p0 = new_cells[pc, np.argmax(plus_old == cells[mc, b_corner][:, None], axis=1)]
    p1 = new_cells[pc, np.argmax(plus_old == cells[mc, a_corner][:, None], axis=1)]
    added = np.stack([m0, m1, p0, p1], axis=1)

    old_if = mesh.interfaces
    if old_if.size:  # minus cell on the right of m0 -> m1, plus cell on the left of p0 -> p1
        minus = _follow_edges(cells, new_cells, old_if[:, [1, 0]], n, split)[:, [1, 0]]
        plus = _follow_edges(cells, new_cells, old_if[:, 2:], n, split)
        old_if = np.concatenate([minus, plus], axis=1)
    node_sets = copied_node_sets(mesh.node_sets, parent, n)
    edge_sets = {name: _follow_edges(cells, new_cells, np.asarray(e, dtype=np.int64).reshape(-1, 2),
                                     n, split)
                 for name, e in mesh.edge_sets.items()}
    return replace(
        mesh,
        nodes=mesh.nodes[parent],
        cells=new_cells,
        interfaces=np.concatenate([old_if, added]),
        node_sets=node_sets,
        edge_sets=edge_sets,
        face_sets={k: v.copy() for k, v in mesh.face_sets.items()},
        regions={k: np.array(v, copy=True) for k, v in mesh.regions.items()},
    )


def tied_nodes(mesh: Mesh) -> np.ndarray:
    """Representative node of each node, (n_nodes,): the lowest index among the nodes joined by
    interface node pairs. Mapping dofs through it ties every interface exactly (no jump)."""
    i = mesh.interfaces
    half = i.shape[1] // 2  # (minus nodes, plus nodes): 2 + 2 in 2D, 3 + 3 or 4 + 4 in 3D
    rows = i[:, :half].ravel()
    cols = i[:, half:].ravel()
    n = mesh.n_nodes
    graph = sp.coo_matrix((np.ones(rows.size, dtype=np.int8), (rows, cols)), shape=(n, n))
    labels = connected_components(graph, directed=False)[1]
    rep = np.full(labels.max(initial=-1) + 1, n, dtype=np.int64)
    np.minimum.at(rep, labels, np.arange(n))
    return rep[labels]


def at_junctions(mesh: Mesh, nodes: np.ndarray, root: np.ndarray | None = None) -> np.ndarray:
    """Whether each node is a copy of a node split into three copies or more (surfaces meeting at a
    junction); ``root``: :func:`tied_nodes` of the mesh, if made already."""
    root = tied_nodes(mesh) if root is None else root
    return np.bincount(root, minlength=mesh.n_nodes)[root[nodes]] >= 3


def looped_pairs_by_set(minus: list[np.ndarray], plus: list[np.ndarray], n_nodes: int) -> list[np.ndarray]:
    """:func:`looped_pairs` of the pairs of several sets together (a loop may run through several
    sets), split back into one mask per set."""
    looped = looped_pairs(np.concatenate(minus), np.concatenate(plus), n_nodes)
    return list(np.split(looped, np.cumsum([m.shape[0] for m in minus])[:-1]))


def looped_pairs(minus: np.ndarray, plus: np.ndarray, n_nodes: int | None = None) -> np.ndarray:
    """For each node pair (an interface point: copies minus, plus of one node), whether it lies on a
    loop of pairs: the copies of a node inside the mesh split on every edge round it, each tied to
    the next. Held by the others, such a pair has no jump (a crack tip inside the mesh stays shut);
    a pair on no loop (a bridge of the graph of copies: a boundary node's fan, a crack's own pair)
    can open alone. (n_pairs,) bool; Tarjan's bridges, O(pairs)."""
    m, p = np.asarray(minus, dtype=np.int64), np.asarray(plus, dtype=np.int64)
    ends, local = np.unique(np.concatenate([m, p]), return_inverse=True)
    a, b = local[:m.size].tolist(), local[m.size:].tolist()
    adjacent: list[list[tuple[int, int]]] = [[] for _ in range(ends.size)]
    for e, (x, y) in enumerate(zip(a, b)):
        adjacent[x].append((y, e))
        adjacent[y].append((x, e))
    found = [-1] * ends.size  # discovery time
    low = [0] * ends.size
    bridge = np.zeros(m.size, dtype=bool)
    clock = 0
    for root in range(ends.size):
        if found[root] >= 0:
            continue
        found[root] = low[root] = clock
        clock += 1
        stack = [(root, -1, iter(adjacent[root]))]
        while stack:
            v, through, rest = stack[-1]
            for w, e in rest:
                if e == through:
                    continue
                if found[w] < 0:
                    found[w] = low[w] = clock
                    clock += 1
                    stack.append((w, e, iter(adjacent[w])))
                    break
                low[v] = min(low[v], found[w])
            else:
                stack.pop()
                if stack:
                    u = stack[-1][0]
                    low[u] = min(low[u], low[v])
                    if low[v] > found[u]:
                        bridge[through] = True
    return ~bridge
