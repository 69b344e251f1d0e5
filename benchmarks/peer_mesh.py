"""One Gmsh file (MSH 2.2, ASCII) of the peer problem's block, read by both codes.

N x N squares, each cut into two counter-clockwise triangles along the same diagonal; N even,
so a row of edges lies on y = H/2. Physical groups: surface "bulk"; curves "bottom", "top",
"left", "right" and "crack" (the mid-height line, where the cohesive elements go); point groups
"bottom_left" and "pins" (the two left corners, held in x). Only numpy: runs in either venv.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

# MSH 2.2 element types and physical tags
POINT, LINE, TRIANGLE = 15, 1, 2
GROUPS = {"bottom_left": (0, 1), "pins": (0, 2), "bottom": (1, 3), "top": (1, 4), "left": (1, 5),
          "right": (1, 6), "crack": (1, 7), "bulk": (2, 8)}


def grid(n: int, width: float, height: float) -> tuple[np.ndarray, np.ndarray]:
    """Nodes ((n+1)^2, 2) [m] and counter-clockwise triangles (2 n^2, 3) of the block."""
    x = np.linspace(0.0, width, n + 1)
    y = np.linspace(0.0, height, n + 1)
    nodes = np.stack(np.meshgrid(x, y), axis=-1).reshape(-1, 2)
    i, j = np.meshgrid(np.arange(n), np.arange(n))
    a = (j * (n + 1) + i).ravel()  # lower-left corner of each square
    b, c, d = a + 1, a + n + 2, a + n + 1  # lower-right, upper-right, upper-left
    tris = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    return nodes, tris


def write_block(path: str | Path, n: int, width: float, height: float) -> Path:
    """Write the N x N block with its groups to ``path`` (MSH 2.2 ASCII); returns the path."""
    if n % 2:
        raise ValueError("N must be even (the crack runs along a row of edges at mid-height)")
    nodes, tris = grid(n, width, height)
    row = n + 1
    idx = np.arange(nodes.shape[0]).reshape(row, row)  # [j, i]
    edges = {"bottom": np.stack([idx[0, :-1], idx[0, 1:]], 1),
             "top": np.stack([idx[-1, 1:], idx[-1, :-1]], 1),
             "left": np.stack([idx[1:, 0], idx[:-1, 0]], 1),
             "right": np.stack([idx[:-1, -1], idx[1:, -1]], 1),
             "crack": np.stack([idx[n // 2, :-1], idx[n // 2, 1:]], 1)}
    points = {"bottom_left": [idx[0, 0]], "pins": [idx[0, 0], idx[-1, 0]]}
    lines = []
    tag = 1

    def block(kind: int, name: str, conn: np.ndarray) -> None:
        nonlocal tag
        phys = GROUPS[name][1]
        conn = np.asarray(conn).reshape(len(conn), -1) + 1
        ids = np.arange(tag, tag + conn.shape[0])
        tag += conn.shape[0]
        head = np.column_stack([ids, np.full_like(ids, kind), np.full_like(ids, 2),
                                np.full_like(ids, phys), np.full_like(ids, phys)])
        lines.append(np.column_stack([head, conn]))

    for name, p in points.items():
        block(POINT, name, np.asarray(p))
    for name, e in edges.items():
        block(LINE, name, e)
    block(TRIANGLE, "bulk", tris)
    path = Path(path)
    with path.open("w") as fh:
        fh.write("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$PhysicalNames\n")
        fh.write(f"{len(GROUPS)}\n")
        for name, (dim, phys) in GROUPS.items():
            fh.write(f'{dim} {phys} "{name}"\n')
        fh.write("$EndPhysicalNames\n$Nodes\n")
        fh.write(f"{nodes.shape[0]}\n")
        xyz = np.column_stack([np.arange(1, nodes.shape[0] + 1), nodes, np.zeros(nodes.shape[0])])
        np.savetxt(fh, xyz, fmt=["%d", "%.17g", "%.17g", "%g"])
        fh.write("$EndNodes\n$Elements\n")
        fh.write(f"{tag - 1}\n")
        for arr in lines:
            np.savetxt(fh, arr, fmt="%d")
        fh.write("$EndElements\n")
    return path
