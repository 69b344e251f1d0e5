"""Pictures of deformed meshes in the x-y plane, with embedded discontinuities drawn inside their cells.

A cell's displacement is sampled along its edges from u = N d + [[u]] (H_S - f_S) (paper eq. 19):
for a localized EDE cell the jump shows where the edges cross its surface, and the surface itself
is drawn twice, as its - and + faces (u^- = N d - [[u]] f_S, u^+ = u^- + [[u]]). Hexahedra are
drawn by their z = 0 face (plane strain: every layer deforms alike).
"""

from __future__ import annotations

import numpy as np

from rockfrac.elements import ede_kernel as K
from rockfrac.fem.reference import QUAD4
from rockfrac.mesh.geometry import surface_segment  # noqa: F401 (kept importable here)

EDGE_SAMPLES = 25


def section(mesh, u: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """In-plane cells (n_el, 4), node coordinates (n, 2) and displacements (n, 2) of the x-y section."""
    dim = mesh.dim
    disp = u[: dim * mesh.n_nodes].reshape(-1, dim)[:, :2]
    cells = mesh.cells[:, :4]  # Q4, or the z = 0 face of a VTK hexahedron
    return cells, mesh.nodes[:, :2], disp


def _inverse_map(xe: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Reference coordinates (k, 2) of physical points x (k, 2) in the Q4 with nodes xe (4, 2) (Newton)."""
    xi = np.zeros((x.shape[0], 2))
    for _ in range(30):
        n = QUAD4.shape(xi)
        dn = QUAD4.shape_gradients(xi)
        r = n @ xe - x
        jac = np.einsum("kaj,ai->kij", dn, xe)  # dx_i / dxi_j
        step = np.linalg.solve(jac, r[..., None])[..., 0]
        xi -= step
        if np.abs(step).max() < 1e-13:
            break
    return xi


def cell_displacement(xe, de, xi, jump=None, normal=None):
    """Points X (k, 2) and displacements (k, 2) at reference points xi of a Q4 section cell.

    jump, normal: the cell's [[u]] and surface normal (x-y parts) if it is localized; the surface
    passes through the centroid and f_S sums N_a over the nodes on its + side.
    """
    n = QUAD4.shape(xi)
    x = n @ xe
    disp = n @ de
    if jump is not None:
        xc = xe.mean(axis=0)
        active = (xe - xc) @ normal > 0.0
        f_s = n[:, active].sum(axis=1)
        h_s = ((x - xc) @ normal > 0.0).astype(float)
        disp = disp + np.outer(h_s - f_s, jump)
    return x, disp


def deformed_polylines(built, u: np.ndarray, mag: float) -> dict[str, list[np.ndarray]]:
    """Polylines (each (k, 2) [m]) of the undeformed and deformed cell edges and of the cracks.

    Keys: "undeformed", "deformed", "crack_minus", "crack_plus" (embedded surfaces, deformed) and
    "interface" (deformed CSE node pairs are part of the cells' edges already).
    """
    cells, nodes, disp = section(built.mesh, u)
    ede = built.embedded
    out: dict[str, list[np.ndarray]] = {"undeformed": [], "deformed": [], "crack_minus": [], "crack_plus": []}
    s = np.linspace(-1.0, 1.0, EDGE_SAMPLES)
    edges = [np.column_stack([s, -np.ones_like(s)]), np.column_stack([np.ones_like(s), s]),
             np.column_stack([-s, np.ones_like(s)]), np.column_stack([-np.ones_like(s), -s])]
    ref_loop = np.vstack(edges)
    for e, cell in enumerate(cells):
        xe, de = nodes[cell], disp[cell]
        jump = normal = None
        if ede is not None and ede.e_state[e, K.E_LOC] == 1.0:
            jump = ede.e_state[e, K.E_J:K.E_J + 2]
            normal = ede.e_state[e, K.E_N:K.E_N + 2]
        x, d = cell_displacement(xe, de, ref_loop, jump, normal)
        out["undeformed"].append(x)
        out["deformed"].append(x + mag * d)
        if jump is not None and normal is not None:
            ends = surface_segment(xe, normal)
            pts = ends[0] + np.linspace(0.0, 1.0, EDGE_SAMPLES)[:, None] * (ends[1] - ends[0])
            xi = _inverse_map(xe, pts)
            n = QUAD4.shape(xi)
            active = (xe - xe.mean(axis=0)) @ normal > 0.0
            minus = n @ de - np.outer(n[:, active].sum(axis=1), jump)
            out["crack_minus"].append(pts + mag * minus)
            out["crack_plus"].append(pts + mag * (minus + jump))
    return out


def magnification(built, u: np.ndarray, fraction: float = 0.12, mesh=None) -> float:
    """A round magnification that makes the largest displacement about ``fraction`` of the size (u
    on ``mesh``, by default the built mesh)."""
    _, nodes, disp = section(mesh if mesh is not None else built.mesh, u)
    size = np.ptp(nodes, axis=0).max()
    umax = np.abs(disp).max()
    ede = built.embedded
    if ede is not None and ede.localized().size:
        umax = max(umax, np.abs(ede.e_state[:, K.E_J:K.E_J + 2]).max())
    if umax == 0.0:
        return 1.0
    raw = fraction * size / umax
    return float(10.0 ** np.floor(np.log10(raw)) * (5 if raw / 10.0 ** np.floor(np.log10(raw)) >= 5 else
                                                     2 if raw / 10.0 ** np.floor(np.log10(raw)) >= 2 else 1))


def draw_deformed(ax, lines: dict[str, list[np.ndarray]], title: str) -> None:
    """Undeformed cells dashed grey, deformed cells solid, embedded crack faces red (-) and blue (+)."""
    for x in lines["undeformed"]:
        ax.plot(x[:, 0] * 1e3, x[:, 1] * 1e3, "--", color="0.6", lw=0.8)
    for x in lines["deformed"]:
        ax.plot(x[:, 0] * 1e3, x[:, 1] * 1e3, "-", color="k", lw=1.2)
    for key, style, colour in (("crack_minus", "-", "tab:red"), ("crack_plus", "--", "tab:blue")):
        for x in lines[key]:
            ax.plot(x[:, 0] * 1e3, x[:, 1] * 1e3, style, color=colour, lw=1.6)
    ax.set_aspect("equal")
    ax.set_xlabel("x [mm]")
    ax.set_ylabel("y [mm]")
    ax.set_title(title, fontsize=9)
