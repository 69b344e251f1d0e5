"""Pictures of a cracked, deformed 2D mesh of any size: bulk cells coloured by a cell field, the
open cracks (cohesive interfaces and embedded segments) drawn over them, coloured by their jump.

Works on the same arrays as the ParaView output (`rockfrac.output.vtk.StepFields`), vectorized
with matplotlib collections, so a mesh of 1e5 cells draws in seconds. Hexahedra are drawn by their
z = 0 face (plane strain). A general 3D body (``view="3d"``) is drawn in perspective: its deformed
boundary as a light wireframe and the centres of its yielded interface cells coloured by |jump|.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rockfrac.output.vtk import CellKind, CrackState, StepFields


@dataclass(frozen=True)
class CrackLines:
    """Deformed crack segments (k, 2, 2) [m] and the norm of their jumps (k,) [m]."""

    segments: np.ndarray
    opening: np.ndarray


def _block(fields: StepFields, kind: CellKind) -> int | None:
    for b, kinds in enumerate(fields.cell_data["cell_kind"]):
        if kinds.size and int(kinds[0]) == int(kind):
            return b
    return None


def deformed_points(fields: StepFields, magnification: float) -> np.ndarray:
    """Points (n, 2) [m] moved by ``magnification`` x displacement."""
    return fields.points[:, :2] + magnification * fields.point_data["displacement"][:, :2]


def crack_lines(fields: StepFields, magnification: float, yielded_only: bool = True) -> CrackLines:
    """The cracks to draw: interface cells (midline of the deformed minus and plus edges), by default
    only those that have yielded (plastic now or a plastic jump), and every embedded segment."""
    x = deformed_points(fields, magnification)
    segs, opening = [], []
    for kind in (CellKind.INTERFACE, CellKind.EMBEDDED):
        b = _block(fields, kind)
        if b is None:
            continue
        conn = fields.cells[b][1]
        jump = fields.cell_data["jump"][b]
        keep = np.isfinite(jump).all(axis=1)
        if yielded_only and kind == CellKind.INTERFACE:
            plastic = np.abs(fields.cell_data["plastic_jump"][b]).max(axis=1) > 0.0
            keep &= plastic | (fields.cell_data["state"][b] == int(CrackState.PLASTIC))
        conn, jump = conn[keep], jump[keep]
        if kind == CellKind.INTERFACE:  # VTK quad (m0, m1, p1, p0)
            ends = 0.5 * (x[conn[:, [0, 1]]] + x[conn[:, [3, 2]]])
        else:
            ends = x[conn]
        segs.append(ends)
        opening.append(np.linalg.norm(jump, axis=1))
    if not segs:
        return CrackLines(np.zeros((0, 2, 2)), np.zeros(0))
    return CrackLines(np.concatenate(segs), np.concatenate(opening))


def draw_crack_map(ax, fields: StepFields, magnification: float = 1.0, cell_field: str = "gamma",
                   title: str = "") -> CrackLines:
    """Deformed bulk cells coloured by ``cell_field`` (a scalar cell field of the bulk block), with the
    yielded cracks over them coloured by |jump| [mm]; returns the cracks drawn."""
    from matplotlib.collections import LineCollection, PolyCollection

    x = deformed_points(fields, magnification)
    b = _block(fields, CellKind.BULK)
    if b is None:
        raise ValueError("the fields hold no bulk cells")
    kind, conn = fields.cells[b]
    if kind == "hexahedron":
        conn = conn[:, :4]
    if cell_field not in fields.cell_data:
        raise ValueError(f"unknown cell field {cell_field!r}; known: {sorted(fields.cell_data)}")
    values = fields.cell_data[cell_field][b]
    if values.ndim != 1:
        raise ValueError(f"cell field {cell_field!r} is not a scalar (shape {values.shape})")
    polys = PolyCollection(x[conn] * 1e3, array=values, cmap="Greys", edgecolors="face", linewidths=0.2)
    ax.add_collection(polys)
    ax.figure.colorbar(polys, ax=ax, label=cell_field, shrink=0.6, location="bottom", pad=0.08)
    cracks = crack_lines(fields, magnification)
    if cracks.opening.size:
        lines = LineCollection(list(cracks.segments * 1e3), array=cracks.opening * 1e3, cmap="plasma",
                               linewidths=1.5)
        ax.add_collection(lines)
        ax.figure.colorbar(lines, ax=ax, label="|jump| [mm]", shrink=0.6)
    ax.autoscale_view()
    ax.set_aspect("equal")
    ax.set_xlabel("x [mm]")
    ax.set_ylabel("y [mm]")
    ax.set_title(title or f"deformed x{magnification:g}, {cracks.opening.size} crack segments", fontsize=9)
    return cracks


def yielded_interfaces_3d(fields: StepFields, magnification: float) -> CrackLines:
    """Centres (k, 1, 3) [m] of the deformed interface cells of a 3D body that have yielded, with the
    norms of their jumps (k,) [m]."""
    b = _block(fields, CellKind.INTERFACE)
    if b is None:
        return CrackLines(np.zeros((0, 1, 3)), np.zeros(0))
    x = fields.points + magnification * fields.point_data["displacement"]
    conn = fields.cells[b][1]
    jump = fields.cell_data["jump"][b]
    plastic = np.abs(fields.cell_data["plastic_jump"][b]).max(axis=1) > 0.0
    keep = np.isfinite(jump).all(axis=1) & (plastic | (fields.cell_data["state"][b] == int(CrackState.PLASTIC)))
    return CrackLines(x[conn[keep]].mean(axis=1)[:, None, :], np.linalg.norm(jump[keep], axis=1))


def embedded_surfaces_3d(fields: StepFields, magnification: float) -> CrackLines:
    """The deformed triangles (k, 3, 3) [m] of a 3D body's embedded crack surfaces, with the norms of
    their jumps (k,) [m]."""
    b = next((k for k, (kind, _) in enumerate(fields.cells) if kind == "triangle"
              and int(fields.cell_data["cell_kind"][k][0]) == int(CellKind.EMBEDDED)), None)
    if b is None or not len(fields.cells[b][1]):
        return CrackLines(np.zeros((0, 3, 3)), np.zeros(0))
    x = fields.points + magnification * fields.point_data["displacement"]
    return CrackLines(x[fields.cells[b][1]], np.linalg.norm(fields.cell_data["jump"][b], axis=1))


def draw_crack_map_3d(ax, fields: StepFields, magnification: float = 1.0, title: str = "") -> CrackLines:
    """A 3D axis: the deformed body's outer edges (its bounding wireframe), the yielded interface
    cells' centres and the embedded crack surfaces, coloured by |jump| [mm]; returns the interface
    cells and the surfaces' triangles."""
    x = (fields.points + magnification * fields.point_data["displacement"]) * 1e3
    lo, hi = x.min(axis=0), x.max(axis=0)
    for i in range(3):  # the bounding box's twelve edges
        for a in (lo, hi):
            for b in (lo, hi):
                j, k = (i + 1) % 3, (i + 2) % 3
                p, q = np.empty(3), np.empty(3)
                p[i], q[i] = lo[i], hi[i]
                p[j] = q[j] = a[j]
                p[k] = q[k] = b[k]
                ax.plot(*zip(p, q), color="0.7", linewidth=0.6)
    cracks = yielded_interfaces_3d(fields, magnification)
    if cracks.opening.size:
        c = cracks.segments[:, 0] * 1e3
        dots = ax.scatter(c[:, 0], c[:, 1], c[:, 2], c=cracks.opening * 1e3, cmap="plasma", s=6)
        ax.figure.colorbar(dots, ax=ax, label="|jump| [mm]", shrink=0.6)
    surfaces = embedded_surfaces_3d(fields, magnification)
    if surfaces.opening.size:
        from mpl_toolkits.mplot3d.art3d import Poly3DCollection

        patches = Poly3DCollection(list(surfaces.segments * 1e3), cmap="plasma", edgecolor="none")
        patches.set_array(surfaces.opening * 1e3)
        ax.add_collection3d(patches)
        ax.figure.colorbar(patches, ax=ax, label="embedded |jump| [mm]", shrink=0.6)
    ax.set_xlabel("x [mm]")
    ax.set_ylabel("y [mm]")
    ax.set_zlabel("z [mm]")
    ax.set_box_aspect(tuple(np.maximum(hi - lo, 1e-9 * max(hi - lo))))
    ax.set_title(title or f"deformed x{magnification:g}, {cracks.opening.size} yielded interface cells",
                 fontsize=9)
    return CrackLines(np.concatenate([np.repeat(cracks.segments, 3, axis=1), surfaces.segments]),
                      np.concatenate([cracks.opening, surfaces.opening]))


def save_crack_map(path, fields: StepFields, magnification: float, cell_field: str = "gamma",
                   title: str = "", view: str = "plane") -> CrackLines:
    """Write the crack map of one step to ``path`` (PNG): ``view`` "plane" (2D, or a plane-strain
    slab's z = 0 face) or "3d" (a general 3D body); returns the cracks drawn."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    if view == "3d":
        fig = plt.figure(figsize=(7.0, 8.0))
        cracks = draw_crack_map_3d(fig.add_subplot(projection="3d"), fields, magnification, title)
        fig.savefig(path, dpi=150, bbox_inches="tight")
        plt.close(fig)
        return cracks
    fig, ax = plt.subplots(figsize=(6.0, 8.0))
    cracks = draw_crack_map(ax, fields, magnification, cell_field, title)
    fig.savefig(path, dpi=150, bbox_inches="tight")
    plt.close(fig)
    return cracks
