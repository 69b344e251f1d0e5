"""Kernel rates: elastic Q4 stiffness + CSR scatter, cohesive traction laws, Drucker-Prager return map.

One command (``python benchmarks/kernels.py``, ``make kernels``): times the engine's compiled
kernels on synthetic but realistic inputs, on one core (``NUMBA_NUM_THREADS=1`` is set before
Numba loads unless ``--threads`` says otherwise), and compares the rates with the targets of the
issue "Speed at a million unknowns": elastic Q4 assembly (values and scatter into an existing CSR
pattern) >= 1e6 elements/s, traction-law and Drucker-Prager updates >= 1e7 points/s. Each kernel
is timed ``--repeat`` times after a warm-up call; the best time is reported (the machine is
shared). Where the engine keeps a reference path (the kernel before optimisation), it is timed
too, so one run shows before and after. Results go to ``benchmarks/results/kernels.json``;
``--dp-only`` re-measures the Drucker-Prager rows alone and merges them into it.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

HERE = Path(__file__).parent


def _threads_from_argv() -> str:
    for i, a in enumerate(sys.argv):
        if a == "--threads" and i + 1 < len(sys.argv):
            return sys.argv[i + 1]
    return "1"


os.environ["NUMBA_NUM_THREADS"] = _threads_from_argv()  # before numba is imported

import numpy as np  # noqa: E402

sys.path.insert(0, str(HERE))
from run import machine, replace_table  # noqa: E402

ELEMENT_TARGET = 1.0e6  # elements/s, elastic Q4 values + scatter, one core
POINT_TARGET = 1.0e7  # integration points/s, traction law and Drucker-Prager updates


def best_time(fn, repeat: int) -> float:
    """Smallest wall time [s] of ``repeat`` calls of fn() after one warm-up call."""
    fn()
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def q4_mesh(n: int, seed: int = 0):
    """n x n distorted unit-square Q4 mesh: nodes (m, 2) [m], cells (n*n, 4)."""
    rng = np.random.default_rng(seed)
    h = 1.0 / n
    x, y = np.meshgrid(np.linspace(0, 1, n + 1), np.linspace(0, 1, n + 1), indexing="xy")
    nodes = np.column_stack([x.ravel(), y.ravel()])
    inner = (nodes[:, 0] > 0) & (nodes[:, 0] < 1) & (nodes[:, 1] > 0) & (nodes[:, 1] < 1)
    nodes[inner] += rng.uniform(-0.2 * h, 0.2 * h, size=(inner.sum(), 2))
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="xy")
    a = (j * (n + 1) + i).ravel()
    cells = np.column_stack([a, a + 1, a + n + 2, a + n + 1])
    return nodes, cells


def elastic_q4(n_side: int, repeat: int) -> dict:
    """Elastic Q4 plane-strain stiffness values and their scatter into an existing CSR pattern."""
    from rockfrac.elements.solid import SolidGeometry
    from rockfrac.fem import kinematics as kin
    from rockfrac.fem.assembly import Pattern, scatter_matrix
    from rockfrac.fem.reference import QUAD4
    from rockfrac.laws.elastic import elasticity

    nodes, cells = q4_mesh(n_side)
    geo = SolidGeometry(nodes, cells, QUAD4)
    d = elasticity(1.5e7, 0.3, 2)
    pattern = Pattern.build(2 * nodes.shape[0], [geo.dofs])
    slots = pattern.slots[0]
    data = np.zeros(pattern.nnz)
    n_el = cells.shape[0]
    out = {"elements": n_el, "nnz": pattern.nnz}

    def reference():
        data[:] = 0.0
        scatter_matrix(data, slots, kin.elastic_blocks(geo.grads, geo.wdet, d))

    t_ref = best_time(reference, repeat)
    ref_data = data.copy()
    t_values = best_time(lambda: kin.elastic_blocks(geo.grads, geo.wdet, d), repeat)
    ke = kin.elastic_blocks(geo.grads, geo.wdet, d)
    t_scatter = best_time(lambda: scatter_matrix(data, slots, ke), repeat)
    out.update({"reference_s": t_ref, "reference_rate": n_el / t_ref,
                "reference_values_s": t_values, "reference_scatter_s": t_scatter})
    fused = getattr(kin, "elastic_assemble", None)
    if fused is not None:
        slots32 = pattern.slots32(0) if hasattr(pattern, "slots32") else slots

        def fast():
            data[:] = 0.0
            fused(geo.grads, geo.wdet, d, slots32, data)

        t_fast = best_time(fast, repeat)
        out.update({"fast_s": t_fast, "fast_rate": n_el / t_fast,
                    "max_rel_diff": float(np.max(np.abs(data - ref_data)) / np.max(np.abs(ref_data)))})
    return out


def cohesive_inputs(n: int, plastic: bool, rigid: bool, seed: int = 1):
    """Points with random frames; EP: jump increments below / beyond yield; RP: multipliers inside / outside."""
    from rockfrac.laws.cohesive_params import N_STATE, CohesiveLaw

    rng = np.random.default_rng(seed)
    law = CohesiveLaw(GfI=1e4, GfII=1e4, chi_p=15680.0, chi_r=0.0, c_p=9053.0, c_r=0.0, phi_p=0.5236,
                      phi_r=0.0, psi_p=0.087, alpha_chi=2e3, alpha_c=2e3, alpha_phi=9e2, alpha_psi=9e2,
                      kn=None if rigid else 1e9, kt=None if rigid else 1e9)
    ang = rng.uniform(0, np.pi, n)
    frame = np.empty((n, 2, 2))
    frame[:, 0, 0], frame[:, 0, 1] = np.cos(ang), np.sin(ang)
    frame[:, 1, 0], frame[:, 1, 1] = -np.sin(ang), np.cos(ang)
    weight = rng.uniform(0.5e-3, 1.5e-3, n)
    # local increments: elastic ~ 1e-7 m (T ~ 100 Pa), plastic: shear beyond the cohesion
    loc = np.column_stack([rng.uniform(-1e-7, 1e-7, n), rng.uniform(-1e-7, 1e-7, n)])
    if plastic:
        loc[:, 0] = np.sign(loc[:, 0]) * rng.uniform(2e-5, 4e-5, n)
        loc[:, 1] = rng.uniform(0.0, 2e-6, n)
    djump = np.einsum("pji,pj->pi", frame, loc)  # R^T local
    return law, frame, weight, djump, np.zeros((n, N_STATE)), np.zeros((n, 2, 2))


def cohesive_ep(n: int, plastic: bool, repeat: int) -> dict:
    """EP traction law + pair blocks at n points (paper eq. 30-31)."""
    from rockfrac.elements import cse

    law, frame, weight, djump, s_old, d_old = cohesive_inputs(n, plastic, rigid=False)
    p = law.as_array()
    s_new, d_new = np.empty_like(s_old), np.empty_like(d_old)
    fe, ke = np.empty((n, 4)), np.empty((n, 4, 4))
    status = np.empty(n, dtype=np.int64)
    t = best_time(lambda: cse.ep_points(frame, weight, djump, s_old, d_old, p, s_new, d_new, fe, ke, status), repeat)
    return {"points": n, "s": t, "rate": n / t, "plastic_share": float(np.mean(status == 1)),
            "failed": int(np.sum(status < 0))}


def cohesive_rp(n: int, plastic: bool, repeat: int) -> dict:
    """RP augmented-Lagrangian return + blocks at n points (paper eq. 32-34)."""
    from rockfrac.elements import cse

    law, frame, weight, djump, s_old, d_old = cohesive_inputs(n, plastic, rigid=True)
    p = law.as_array()
    aug = 1e9
    rng = np.random.default_rng(2)
    lam = rng.uniform(-100.0, 100.0, (n, 2))  # constrained: |T| well inside the surface
    if not plastic:
        djump[:] = 1e-12 * rng.uniform(-1, 1, (n, 2))
    s_new, d_new = np.empty_like(s_old), np.empty_like(d_old)
    fe, ke = np.empty((n, 6)), np.empty((n, 6, 6))
    status = np.empty(n, dtype=np.int64)
    switched = np.empty(n, dtype=np.int64)
    eps = np.zeros(n)
    pinned = np.zeros(n, dtype=bool)
    mode_prev = np.zeros(n)
    t = best_time(lambda: cse.rp_points(frame, weight, djump, lam, aug, eps, pinned, s_old, d_old, mode_prev, p,
                                        s_new, d_new, fe, ke, status, switched), repeat)
    return {"points": n, "s": t, "rate": n / t, "plastic_share": float(np.mean(status == 1)),
            "failed": int(np.sum(status < 0))}


def dp_law():
    from rockfrac.laws.drucker_prager_params import DruckerPrager

    return DruckerPrager(E=1.5e7, nu=0.3, beta=0.480385, b=0.321597, kappa0=7532.54, H=43802.9)


def dp_strains(n: int, plastic: bool, seed: int = 3) -> np.ndarray:
    """Plane-strain strains (n, 6): elastic ~1e-5, plastic: compression with shear ~1e-2."""
    rng = np.random.default_rng(seed)
    eps = np.zeros((n, 6))
    scale = 1e-2 if plastic else 1e-5
    eps[:, 0] = rng.uniform(0.3, 0.8, n) * scale if plastic else rng.uniform(-0.3, 0.3, n) * scale
    eps[:, 1] = -rng.uniform(0.5, 1.0, n) * scale
    eps[:, 3] = rng.uniform(-0.5, 0.5, n) * scale
    return eps


_REFERENCE = {}


def reference_kernels() -> dict:
    """The Drucker-Prager loops as they were before the optimisations, compiled here for the
    comparison: one allocating return map per point and one allocating cell per element, both with
    the return map as it was (``drucker_prager.return_map_reference_into``: trial stress by the 6 x 6
    product, the cone tangent by the i, j loop with a division per entry, a call per point)."""
    if not _REFERENCE:
        import numba as nb

        from rockfrac.elements.plastic_solid import element_scratch, plane_integrate_point, plane_point_strain
        from rockfrac.laws import drucker_prager as dp

        @nb.njit(parallel=True)
        def points(eps, s_old, p, sigma, c, s_new, status):
            for i in nb.prange(eps.shape[0]):
                status[i] = dp.return_map_reference(eps[i], s_old[i], p, sigma[i], c[i], s_new[i])

        @nb.njit
        def plane_cell(grads, wdet, ue, s_old, p, s_new, sigma, fe, ke):
            """plastic_solid.dp_element (plane cells) with the reference return map."""
            k, mu = dp.moduli(p)
            ce = dp.elastic_matrix(p)
            b, cb, eps6, c6, work, idx = element_scratch(grads.shape[1], grads.shape[2])
            fe[:] = 0.0
            ke[:, :] = 0.0
            status = 0
            for q in range(grads.shape[0]):
                plane_point_strain(grads[q], ue, eps6)
                st = dp.return_map_reference_into(eps6, s_old[q], p, k, mu, ce, work, sigma[q], c6, s_new[q])
                if st < 0:
                    status = st
                    continue
                plane_integrate_point(grads[q], wdet[q], sigma[q], c6, fe, ke, cb)
            return status

        @nb.njit(parallel=True)
        def blocks(grads, wdet, ue, s_old, p, s_new, sigma, fe, ke, status):
            for e in nb.prange(grads.shape[0]):
                status[e] = plane_cell(grads[e], wdet[e], ue[e], s_old[e], p, s_new[e], sigma[e], fe[e], ke[e])

        _REFERENCE.update(points=points, blocks=blocks)
    return _REFERENCE


def rel_diff(a: np.ndarray, ref: np.ndarray) -> float:
    """max |a - ref| / max |ref| (0.0: the same bits)."""
    scale = float(np.max(np.abs(ref)))
    return float(np.max(np.abs(a - ref))) / scale if scale > 0 else float(np.max(np.abs(a - ref)))


def dp_points(n: int, plastic: bool, repeat: int) -> dict:
    """Drucker-Prager return map + consistent tangent at n points."""
    from rockfrac.laws import drucker_prager as dp
    from rockfrac.laws.drucker_prager_params import N_STATE

    p = dp_law().as_array()
    eps = dp_strains(n, plastic)
    s_old = np.zeros((n, N_STATE))
    s_new = np.empty_like(s_old)
    sigma, c = np.empty((n, 6)), np.empty((n, 6, 6))
    status = np.empty(n, dtype=np.int64)
    ref = reference_kernels()["points"]
    t_ref = best_time(lambda: ref(eps, s_old, p, sigma, c, s_new, status), repeat)
    sig_ref, c_ref = sigma.copy(), c.copy()
    st_ref = status.copy()
    t = best_time(lambda: dp.return_map_points(eps, s_old, p, sigma, c, s_new, status), repeat)
    return {"points": n, "s": t, "rate": n / t, "reference_s": t_ref, "reference_rate": n / t_ref,
            "identical": bool(np.array_equal(sigma, sig_ref) and np.array_equal(c, c_ref)),
            "same_status": bool(np.array_equal(status, st_ref)),
            "max_rel_diff_sigma": rel_diff(sigma, sig_ref), "max_rel_diff_tangent": rel_diff(c, c_ref),
            "plastic_share": float(np.mean(status > 0)), "failed": int(np.sum(status < 0))}


def dp_elements(n_side: int, plastic: bool, repeat: int) -> dict:
    """Drucker-Prager Q4 cells (4 points each): return maps, fe, ke, then the scatter into CSR."""
    from rockfrac.elements.plastic_solid import DruckerPragerSolid
    from rockfrac.fem.assembly import Pattern, scatter_matrix, scatter_vector
    from rockfrac.fem.reference import QUAD4

    nodes, cells = q4_mesh(n_side)
    solid = DruckerPragerSolid(nodes, cells, QUAD4, dp_law())
    scale = 1e-2 if plastic else 1e-5
    u = np.zeros(2 * nodes.shape[0])
    u[0::2] = 0.3 * scale * (nodes[:, 0] - 0.5)
    u[1::2] = -scale * nodes[:, 1] + 0.3 * scale * nodes[:, 0]
    pattern = Pattern.build(u.size, [solid.dofs])
    data = np.zeros(pattern.nnz)
    f = np.zeros(u.size)
    slots = pattern.slots[0]

    ref = reference_kernels()["blocks"]
    ue = lambda: np.ascontiguousarray(u[solid.dofs])  # noqa: E731
    n_el, nd = solid.dofs.shape

    def reference():  # as before: fresh fe, ke per call, allocating kernels
        fe, ke = np.empty((n_el, nd)), np.empty((n_el, nd, nd))
        ref(solid.grads, solid.wdet, ue(), solid.state, solid.p, solid.trial, solid.trial_sigma, fe, ke,
            solid.status)
        scatter_vector(f, solid.dofs, fe)
        scatter_matrix(data, slots, ke)
        return ke

    def evaluate_scatter():
        ev = solid.evaluate(u, u)
        scatter_vector(f, solid.dofs, ev.fe)
        scatter_matrix(data, slots, ev.ke)
        return ev.ke

    t_ref = best_time(reference, repeat)
    ke_ref = reference()
    solid.reuse_buffers = True  # as the model runs it
    t = best_time(evaluate_scatter, repeat)
    ke = evaluate_scatter()
    same = bool(np.array_equal(ke, ke_ref))
    diff = rel_diff(ke, ke_ref)
    t_eval = best_time(lambda: solid.evaluate(u, u), repeat)
    return {"elements": n_el, "points": 4 * n_el, "s": t, "rate_elements": n_el / t,
            "reference_s": t_ref, "reference_rate_elements": n_el / t_ref, "identical": same, "max_rel_diff": diff,
            "evaluate_s": t_eval, "points_rate_in_cells": 4 * n_el / t_eval,
            "plastic_share": float(np.mean(solid.trial[..., -1] > 0))}


def verdict(rate: float, target: float) -> str:
    return f"{rate:.3g}/s ({'meets' if rate >= target else 'misses'} {target:.0e})"


def dp_same(r: dict, diff: float) -> str:
    """'yes' (same bits), or the largest relative difference from the reference path."""
    if r["identical"]:
        return "yes"
    if not r.get("same_status", True):
        return "NO (status differs)"
    return f"no: rel. diff {diff:.1e}"


def table_lines(res: dict) -> list[str]:
    """Markdown: machine, load, and per kernel the reference (before) and engine (after) rates."""
    info = res["machine"]
    q4, lines = res["elastic_q4"], []
    lines.append(f"Machine: {info['cpu']}, {info['cores']} cores; Numba {info['numba']}; {info['date']}; "
                 f"{res['threads']} thread(s); load average (1 min) {res['load_before'][0]:.1f} before, "
                 f"{res['load_after'][0]:.1f} after.")
    if "dp_run" in res:
        dp = res["dp_run"]
        lines.append(f"Drucker-Prager rows re-measured on their own (`kernels.py --dp-only`): {dp['machine']['date']}; "
                     f"{dp['threads']} thread(s); load average (1 min) {dp['load_before'][0]:.1f} before, "
                     f"{dp['load_after'][0]:.1f} after; the other rows are from the run above.")
    lines += ["", "| kernel | n | before (reference path) | after (engine) | target | after meets it | same bits |",
              "|---|---|---|---|---|---|---|"]

    def row(name, n, before, after, target, same):
        ok = "yes" if after >= target else "no"
        b = before if isinstance(before, str) else f"{before:.3g}/s"
        lines.append(f"| {name} | {n:.0e} | {b} | {after:.3g}/s | {target:.0e}/s | {ok} | {same} |")

    row("elastic Q4: values + scatter into CSR [elements]", q4["elements"], q4["reference_rate"],
        q4.get("fast_rate", q4["reference_rate"]), ELEMENT_TARGET,
        "yes" if q4.get("max_rel_diff") == 0.0 else f"rel. diff {q4.get('max_rel_diff')}")
    for kind in ("elastic", "plastic"):
        r = res[f"dp_points_{kind}"]
        row(f"Drucker-Prager return map + tangent, {kind} [points]", r["points"], r["reference_rate"], r["rate"],
            POINT_TARGET, dp_same(r, max(r.get("max_rel_diff_sigma", 0.0), r.get("max_rel_diff_tangent", 0.0))))
    for kind in ("elastic", "plastic"):
        r = res[f"dp_q4_{kind}"]
        row(f"Drucker-Prager Q4 cells, {kind}: 4 return maps, fe, ke, scatter [elements]", r["elements"],
            r["reference_rate_elements"], r["rate_elements"], ELEMENT_TARGET, dp_same(r, r.get("max_rel_diff", 0.0)))
    for law in ("ep", "rp"):
        for kind in ("elastic", "plastic"):
            r = res[f"cohesive_{law}_{kind}"]
            label = {"ep": "EP", "rp": "RP"}[law]
            state = {"elastic": "elastic" if law == "ep" else "constrained", "plastic": "plastic"}[kind]
            row(f"{label} traction law + pair blocks, {state} [points]", r["points"], "(no reference kept: see text)",
                r["rate"], POINT_TARGET, "-")
    return lines


def write_table(res: dict) -> None:
    replace_table("kernels-table", table_lines(res))


def run_dp(res: dict, args) -> None:
    for kind in ("elastic", "plastic"):
        res[f"dp_points_{kind}"] = dp_points(args.points, kind == "plastic", args.repeat)
        print("dp_points", kind, json.dumps(res[f"dp_points_{kind}"]), flush=True)
    for kind in ("elastic", "plastic"):
        res[f"dp_q4_{kind}"] = dp_elements(args.elements // 2, kind == "plastic", args.repeat)
        print("dp q4", kind, json.dumps(res[f"dp_q4_{kind}"]), flush=True)


def dp_only(args) -> None:
    """The Drucker-Prager rows alone, merged into results/kernels.json (other rows as they were)."""
    path = HERE / "results" / "kernels.json"
    res = json.loads(path.read_text())
    res.pop("dp_run", None)
    run = {"machine": machine(), "threads": int(os.environ["NUMBA_NUM_THREADS"]), "load_before": os.getloadavg()}
    run_dp(res, args)
    run["load_after"] = os.getloadavg()
    res["dp_run"] = run
    for kind in ("elastic", "plastic"):
        print(f"dp_points_{kind}", verdict(res[f"dp_points_{kind}"]["rate"], POINT_TARGET))
    if not args.no_save:
        path.write_text(json.dumps(res, indent=1))
        write_table(res)
    print("\n".join(table_lines(res)))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--threads", default="1", help="NUMBA_NUM_THREADS (default 1: one core)")
    ap.add_argument("--elements", type=int, default=1000, help="Q4 mesh is N x N (default 1000)")
    ap.add_argument("--points", type=int, default=1_000_000, help="points per law kernel")
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--no-save", action="store_true", help="print only")
    ap.add_argument("--dp-only", action="store_true",
                    help="re-measure only the Drucker-Prager rows; the other rows keep their figures "
                         "from results/kernels.json (the table says when each part ran)")
    args = ap.parse_args()
    if args.dp_only:
        dp_only(args)
        return
    load = os.getloadavg()
    res = {"machine": machine(), "threads": int(os.environ["NUMBA_NUM_THREADS"]), "load_before": load}
    res["elastic_q4"] = elastic_q4(args.elements, args.repeat)
    print("elastic Q4", json.dumps(res["elastic_q4"]), flush=True)
    for name, fn in (("cohesive_ep", cohesive_ep), ("cohesive_rp", cohesive_rp), ("dp_points", dp_points)):
        for kind in ("elastic", "plastic"):
            res[f"{name}_{kind}"] = fn(args.points, kind == "plastic", args.repeat)
            print(name, kind, json.dumps(res[f"{name}_{kind}"]), flush=True)
    for kind in ("elastic", "plastic"):
        res[f"dp_q4_{kind}"] = dp_elements(args.elements // 2, kind == "plastic", args.repeat)
        print("dp q4", kind, json.dumps(res[f"dp_q4_{kind}"]), flush=True)
    res["load_after"] = os.getloadavg()
    q4 = res["elastic_q4"]
    print("elastic Q4 reference:", verdict(q4["reference_rate"], ELEMENT_TARGET))
    if "fast_rate" in q4:
        print("elastic Q4 fused:", verdict(q4["fast_rate"], ELEMENT_TARGET))
    for k, v in res.items():
        if k.startswith(("cohesive", "dp_points")):
            print(k, verdict(v["rate"], POINT_TARGET))
    if not args.no_save:
        (HERE / "results").mkdir(exist_ok=True)
        (HERE / "results" / "kernels.json").write_text(json.dumps(res, indent=1))
        write_table(res)
    print("\n".join(table_lines(res)))


if __name__ == "__main__":
    main()
