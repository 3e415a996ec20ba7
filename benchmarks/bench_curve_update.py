"""Curve-update latency (add a curve, both directions solved) on FAUST tr_reg_000 -> tr_reg_011.

For each energy (``curves``, the paper's; ``combined``, curves plus wave kernel signatures and kernel maps
along the curves, the default) it compares, at k = 30, 60, 120, 200: our update (restriction + re-sum +
per-column exact systems, both directions), the paper's conjugate gradients (Algorithm 2) on the same
energy, warm-started from the previous map, both directions, and a dense direct solve of the k^2 x k^2
system (k <= 60); ``--k`` picks other sizes. Also: texture transfer to a ~30k-vertex mesh (TOSCA cat). Prints
one JSON object.

Besides wall-clock medians it reports CPU medians (all threads of the process): on a machine shared with other work
they are the steadier figures. ``factorisations_cpu_ms`` is the CPU time of the update's 2k column factorisations
alone (one thread, the same systems), and ``speedup_bound_two_cores`` the CG's CPU time over half of it: the most an
update built on those factorisations can gain on two otherwise idle cores (docs/performance.md, the update's floor).

The combined energy is measured without its landmark prior (``prior_weight`` 0), so that the map keeps its size
and the CG comparison has the same energy: in the service the prior is computed in the background and enters an
edit's solve as a fixed term on the right-hand side and the diagonal, which costs the update nothing.
"""

import argparse
import json

import numpy as np

from benchmarks.common import bench_store, machine, median_ms, median_wall_and_cpu_ms, shared_data
from curvefm.fmap import CombinedMapSolver, CurveMapSolver, FunctionTransfer, conjugate_gradient_solve, solve_both
from curvefm.geometry import farthest_point_sampling, load_mesh, shortest_path
from curvefm.runtime import limit_blas_threads

REPEAT = 31
SOLVERS = {"curves": CurveMapSolver, "combined": CombinedMapSolver}
WITHOUT_PRIOR = {"curves": {}, "combined": {"prior_weight": 0.0}}


def curve_paths(mesh, count):
    ends = farthest_point_sampling(mesh, 2 * count)
    return [shortest_path(mesh.edge_graph, a, b) for a, b in zip(ends[0::2], ends[1::2], strict=True)]


def update_latency(M, bM, N, bN, k, paths, energy):
    solver = SOLVERS[energy](M.vertices, bM, N.vertices, bN, k=k, **WITHOUT_PRIOR[energy])
    solver.add_curves([(p, p, 1.0) for p in paths[:-1]])
    last = paths[-1]

    def add_and_remove():
        cid = solver.add_curve(last, last)
        solver.remove_curve(cid)

    ours, ours_cpu = (ms / 2 for ms in median_wall_and_cpu_ms(add_and_remove, REPEAT))  # two updates per call
    solver.add_curve(last, last)
    G_M, G_N, B = solver.normal_equations()
    previous = SOLVERS[energy](M.vertices, bM, N.vertices, bN, k=k, **WITHOUT_PRIOR[energy])
    previous.add_curves([(p, p, 1.0) for p in paths[:-1]])
    iterations = []

    def paper_cg():
        C1, it1 = conjugate_gradient_solve(G_N, B, solver.lam_N, solver.lam_M, solver.alpha, C0=previous.C_MN)
        C2, it2 = conjugate_gradient_solve(G_M, B.T, solver.lam_M, solver.lam_N, solver.alpha, C0=previous.C_NM)
        iterations.append(it1 + it2)
        return C1

    cg, cg_cpu = median_wall_and_cpu_ms(paper_cg, 3 if k >= 120 else REPEAT)
    C_cg = paper_cg()
    weight = solver.commutativity_weight
    _, factorisations_cpu = median_wall_and_cpu_ms(
        lambda: solve_both(G_N, G_M, B, solver.lam_N, solver.lam_M, weight), REPEAT
    )
    result = {
        "energy": energy,
        "k": k,
        "ours_ms": round(ours, 2),
        "paper_cg_warm_ms": round(cg, 2),
        "paper_cg_iterations_both": int(np.median(iterations)),
        "speedup_vs_cg": round(cg / ours, 1),
        "ours_cpu_ms": round(ours_cpu, 2),
        "paper_cg_cpu_ms": round(cg_cpu, 2),
        "speedup_vs_cg_cpu": round(cg_cpu / ours_cpu, 1),
        "factorisations_cpu_ms": round(factorisations_cpu, 2),
        "speedup_bound_two_cores": round(cg_cpu / (factorisations_cpu / 2), 1),
        "max_rel_diff_vs_cg": float(np.abs(C_cg - solver.C_MN).max() / np.abs(solver.C_MN).max()),
    }
    if k <= 60:
        D = (solver.lam_N[:, None] - solver.lam_M[None, :]) ** 2

        def dense():
            H = np.kron(np.eye(k), G_N) + solver.alpha * np.diag(D.T.ravel())
            return np.linalg.solve(H, B.T.ravel())

        result["dense_k2_one_direction_ms"] = round(median_ms(dense, 3), 1)
    return result


def transfer_latency(store):
    cat = load_mesh(shared_data() / "tosca" / "cat0.off")
    basis = store.ensure_basis(cat, 120)
    uv = cat.vertices[:, :2]
    carrier = FunctionTransfer(basis, basis, uv)
    C = np.eye(120) + 0.01 * np.random.default_rng(0).standard_normal((120, 120))
    return {"vertices": cat.n_vertices, "k": 120, "uv_transfer_ms": round(median_ms(lambda: carrier.apply(C), 50), 2)}


def main():
    parser = argparse.ArgumentParser(description="curve-update latency against the paper's CG")
    parser.add_argument("--k", type=int, nargs="+", default=[30, 60, 120, 200], help="map sizes (default: %(default)s)")
    sizes = parser.parse_args().k
    data, store = shared_data(), bench_store()
    M, N = load_mesh(data / "faust" / "tr_reg_000.off"), load_mesh(data / "faust" / "tr_reg_011.off")
    bM, bN = store.ensure_basis(M, 200), store.ensure_basis(N, 200)
    paths = curve_paths(M, 10)
    updates = [update_latency(M, bM, N, bN, k, paths, energy) for energy in SOLVERS for k in sizes]
    print(
        json.dumps(
            {
                "benchmark": "curve_update",
                "machine": machine(),
                "pair": "FAUST tr_reg_000 -> tr_reg_011",
                "curves": 10,
                "update_both_directions": updates,
                "transfer": transfer_latency(store),
            },
            indent=1,
        )
    )


if __name__ == "__main__":
    limit_blas_threads()
    main()
