"""Does descriptor commutativity help the combined energy? (issue 13). Mean geodesic error / sqrt(area), source
-> target, k = 120, ground-truth curves (``experiments/combined_weights.py``'s protocol: 2n farthest points among the
vertices with a known partner, consecutive pairs joined), both nearest-neighbour conversions (``both``: the
embedding of C_MN and C_NM together, the converter's default; ``single``: each direction from its own map, as
pyFM converts). Prints one JSON object. Three families of maps on each pair and curve count:

* ``combined``: the default combined energy (:mod:`curvefm.fmap.combined`), and the same energy plus
  NO17's descriptor commutativity ``w_c / q sum_f ||C X_f - Y_f C||^2 / s_f`` on the leading kc x kc block of C,
  with the multiplication operators of the wave kernel signatures and of the wave kernel maps at the curves'
  endpoints (pyFM's filters), each operator divided by its expected size under a random orthogonal map ``s_f``.
  Solved exactly: the columns j >= kc are untouched; for j < kc the rows >= kc are eliminated (Schur
  complements of the per-column systems), leaving one dense kc^2 system with the commutativity Hessian added.
* ``no17``: the ``no17`` method given the curves' endpoints as landmarks (k = 50, exact).
* ``no17+curves``: the same energy at k = 50 plus the curve terms (the curve energy's normal equations on the
  leading 50 x 50 block), weight ``w`` times the descriptor term's size at C = 0 over trace(G); exact.
* ``no17, 3 per curve``: ``no17`` with three landmarks per curve, its ends and the points at half its arc length
  on each shape (what the curve terms assume corresponds).
* ``no17+indicators``: ``no17`` with each curve's indicator function, smoothed by the heat kernel at t = 0.01
  (unit area), added to the descriptors: what the curves say with no correspondence along them.

``arc_mismatch``: the median and largest distance (Euclidean, by sqrt(area) of the target) between the ground-truth
image of a source curve's point at arc-length fraction t and the target curve's point at the same t (t = 1/8 ..
7/8): how far the curve terms' assumed correspondence is from the truth.
"""

import itertools
import json
import sys

import numpy as np
import scipy.linalg

from benchmarks.common import machine
from curvefm import registry
from curvefm.evaluation import ground_truth_curves, score
from curvefm.fmap import (
    CombinedMapSolver,
    CurveMapSolver,
    FunctionalMaps,
    Hints,
    balanced_weights,
    normalised_eigenvalues,
)
from curvefm.fmap.baselines import DescriptorEnergy
from curvefm.fmap.column_solve import column_diagonals
from curvefm.matching import convert
from curvefm.plugins.converters import NearestNeighborParams
from curvefm.plugins.methods import NO17Params, landmark_descriptors, run_no17
from curvefm.runtime import limit_blas_threads
from curvefm.spectral import multiplication_operators, normalised
from experiments.common import ground_truth_pair

PAIRS = [
    ("faust/tr_reg_000.off", "faust/tr_reg_011.off"),
    ("tosca/wolf0.off", "tosca/wolf2.off"),
    ("nonisometric/pyfm_cat_lion/cat-00.off", "nonisometric/pyfm_cat_lion/lion-00.off"),
]
COUNTS = (2, 10)
BLOCK = 30  # kc: the commutativity block (a dense kc^2 system, 900 x 900)
COMM_WEIGHTS = (30, 300)
CURVE_WEIGHTS = (0.01, 0.1)
K_FIT = 50
HEAT_TIME = 0.01


def block_commutativity_hessian(X: np.ndarray, Y: np.ndarray) -> np.ndarray:
    """Half the Hessian of ``sum_f ||C X_f - Y_f C||^2 / s_f / q`` in C's column-major vector (index j kc + a):
    ``sum_f (X_f^2 (x) I + I (x) Y_f^2 - 2 X_f (x) Y_f) / s_f / q`` for operators X on the columns' shape."""
    q, kc, _ = X.shape
    s = np.sum(X**2, axis=(1, 2)) + np.sum(Y**2, axis=(1, 2))
    s -= 2 * np.trace(X, axis1=1, axis2=2) * np.trace(Y, axis1=1, axis2=2) / kc
    weights = 1.0 / (s * q)
    eye = np.eye(kc)
    SX, SY = np.einsum("f,fab,fbc->ac", weights, X, X), np.einsum("f,fab,fbc->ac", weights, Y, Y)
    cross = (X.reshape(q, -1).T * weights) @ Y.reshape(q, -1)
    cross = cross.reshape(kc, kc, kc, kc).transpose(0, 2, 1, 3).reshape(kc * kc, kc * kc)
    return np.kron(SX, eye) + np.kron(eye, SY) - 2 * cross


def coupled_solve(G, B, lam_rows, lam_cols, alpha, Q) -> np.ndarray:
    """The minimiser of the column-separable energy ``(G + diag(E_j)) c_j = B_j`` plus ``vec(C_kc)^T Q vec(C_kc)``
    on the leading kc x kc block (module doc)."""
    k, kc = len(G), int(round(np.sqrt(len(Q))))
    E = column_diagonals(G, lam_rows, lam_cols, alpha)
    C, system, rhs, eliminated = np.zeros_like(B), Q.copy(), np.zeros(kc * kc), []
    for j in range(k):
        A = G + np.diag(E[:, j])
        if j >= kc:
            C[:, j] = scipy.linalg.solve(A, B[:, j], assume_a="pos")
            continue
        Z = scipy.linalg.solve(A[kc:, kc:], np.column_stack([A[kc:, :kc], B[kc:, j]]), assume_a="pos")
        block = slice(j * kc, (j + 1) * kc)
        system[block, block] += A[:kc, :kc] - A[:kc, kc:] @ Z[:, :kc]
        rhs[block] = B[:kc, j] - A[:kc, kc:] @ Z[:, kc]
        eliminated.append(Z)
    x = scipy.linalg.solve(system, rhs, assume_a="pos").reshape(kc, kc)
    for j, Z in enumerate(eliminated):
        C[:kc, j], C[kc:, j] = x[j], Z[:, kc] - Z[:, :kc] @ x[j]
    return C


def endpoint_operators(pair, hints, kc):
    f_M, f_N = landmark_descriptors(pair, hints, NO17Params())
    return multiplication_operators(pair.basis_M, f_M, kc), multiplication_operators(pair.basis_N, f_N, kc)


def combined_with_commutativity(pair, solver, operators, weight) -> FunctionalMaps:
    G_M, G_N, B = solver.normal_equations()
    X, Y = operators
    C_MN = coupled_solve(G_N, B, solver.lam_N, solver.lam_M, solver.alpha, weight * block_commutativity_hessian(X, Y))
    C_NM = coupled_solve(G_M, B.T, solver.lam_M, solver.lam_N, solver.alpha, weight * block_commutativity_hessian(Y, X))
    return FunctionalMaps(C_MN, C_NM)


def no17_with_curves(pair, hints, curve_solver, weight) -> FunctionalMaps:
    """NO17's energy (row-major vec(C), as :class:`curvefm.fmap.DescriptorEnergy`) at K_FIT plus curve terms."""
    params, k = NO17Params(k=K_FIT), K_FIT
    f_M, f_N = landmark_descriptors(pair, hints, params)
    F_M, F_N = pair.basis_M.truncated(k).project(f_M), pair.basis_N.truncated(k).project(f_N)
    X, Y = multiplication_operators(pair.basis_M, f_M, k), multiplication_operators(pair.basis_N, f_N, k)
    lam_M, lam_N = normalised_eigenvalues(pair.basis_M, pair.basis_N, k)
    G_M, G_N, B = (m[:k, :k] for m in curve_solver.normal_equations())
    maps = []
    for F_from, F_to, l_from, l_to, X_from, X_to, G_to, B_to in (
        (F_M, F_N, lam_M, lam_N, X, Y, G_N, B),
        (F_N, F_M, lam_N, lam_M, Y, X, G_M, B.T),
    ):
        w_descr, mu, w_comm = balanced_weights(F_from, F_to, l_from, l_to, X_from, X_to, params.mu, params.w_comm)
        d, q = F_from.shape[1], len(X_from)
        D = (l_to[:, None] - l_from[None, :]) ** 2
        H = w_descr / d * np.kron(np.eye(k), F_from @ F_from.T) + mu * np.diag(D.ravel())
        cross = (X_to.reshape(q, -1).T @ X_from.reshape(q, -1)).reshape(k, k, k, k).transpose(0, 2, 1, 3)
        S_X, S_Y = np.einsum("fab,fbc->ac", X_from, X_from), np.einsum("fab,fbc->ac", X_to, X_to)
        H += w_comm / q * (np.kron(np.eye(k), S_X) + np.kron(S_Y, np.eye(k)) - 2 * cross.reshape(H.shape))
        rhs = w_descr / d * (F_to @ F_from.T).ravel()
        scale = weight * (w_descr / d) * np.sum(F_to[1:] ** 2) / np.trace(G_to)
        H += scale * np.kron(G_to, np.eye(k))
        maps.append(scipy.linalg.solve(H, rhs + scale * B_to.ravel(), assume_a="pos").reshape(k, k))
    return FunctionalMaps(*maps)


def along(vertices, path, fractions) -> list[int]:
    """The path's vertices nearest to the given fractions of its arc length."""
    arc = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(vertices[path], axis=0), axis=1))]
    return [int(path[np.argmin(np.abs(arc - t * arc[-1]))]) for t in fractions]


def arc_mismatch(pair, truth, curves) -> tuple[float, float]:
    partner = dict(zip(truth.ids_X.tolist(), truth.ids_Y.tolist(), strict=True))
    fractions, V_N = np.arange(1, 8) / 8, pair.mesh_N.vertices
    distances = [
        np.linalg.norm(V_N[partner[a]] - V_N[b])
        for pm, pn in curves
        for a, b in zip(along(pair.mesh_M.vertices, pm, fractions), along(V_N, pn, fractions), strict=True)
        if a in partner
    ]
    scale = np.sqrt(pair.mesh_N.area)
    return round(float(np.median(distances)) / scale, 4), round(float(np.max(distances)) / scale, 4)


def points_along_curves(pair, curves, points) -> np.ndarray:
    fractions = np.linspace(0, 1, points)
    pairs = [
        (a, b)
        for pm, pn in curves
        for a, b in zip(
            along(pair.mesh_M.vertices, pm, fractions), along(pair.mesh_N.vertices, pn, fractions), strict=True
        )
    ]
    return np.unique(np.array(pairs, dtype=np.int64), axis=0)


def heat_indicators(basis, paths) -> np.ndarray:
    """Each path's indicator function smoothed by the heat kernel at HEAT_TIME, unit L2 norm (n x len(paths))."""
    indicators = np.zeros((len(basis.mass), len(paths)))
    for column, path in enumerate(paths):
        indicators[path, column] = 1.0
    smoothed = basis.evecs @ (np.exp(-HEAT_TIME * basis.evals)[:, None] * basis.project(indicators))
    return normalised(basis, smoothed)


def no17_with_indicators(pair, hints, curves) -> FunctionalMaps:
    """NO17 (k = K_FIT, exact, balanced weights) with the curves' heat indicators added to its descriptors."""
    params, k = NO17Params(k=K_FIT), K_FIT
    f_M, f_N = landmark_descriptors(pair, hints, params)
    f_M = np.hstack([f_M, heat_indicators(pair.basis_M, [pm for pm, _ in curves])])
    f_N = np.hstack([f_N, heat_indicators(pair.basis_N, [pn for _, pn in curves])])
    F_M, F_N = pair.basis_M.truncated(k).project(f_M), pair.basis_N.truncated(k).project(f_N)
    X, Y = multiplication_operators(pair.basis_M, f_M, k), multiplication_operators(pair.basis_N, f_N, k)
    lam_M, lam_N = normalised_eigenvalues(pair.basis_M, pair.basis_N, k)
    maps = []
    for args in ((F_M, F_N, lam_M, lam_N, X, Y), (F_N, F_M, lam_N, lam_M, Y, X)):
        w_descr, mu, w_comm = balanced_weights(*args, params.mu, params.w_comm)
        maps.append(DescriptorEnergy(*args, mu, w_descr, w_comm).minimiser())
    return FunctionalMaps(*maps)


def candidate_maps(pair, curves):
    """{label: FunctionalMaps} for every configuration in the module doc."""
    hints = Hints.from_curves(curves)
    vertices_and_bases = (pair.mesh_M.vertices, pair.basis_M, pair.mesh_N.vertices, pair.basis_N)
    maps = {}
    with CombinedMapSolver(*vertices_and_bases) as combined, CurveMapSolver(*vertices_and_bases) as curve_only:
        combined.add_curves([(pm, pn, 1.0) for pm, pn in curves])
        curve_only.add_curves([(pm, pn, 1.0) for pm, pn in curves])
        maps["combined"] = FunctionalMaps(combined.C_MN, combined.C_NM)
        operators = endpoint_operators(pair, hints, BLOCK)
        for weight in COMM_WEIGHTS:
            maps[f"combined+comm {weight}"] = combined_with_commutativity(pair, combined, operators, weight)
        maps["no17"] = run_no17(pair, hints, NO17Params())
        for weight in CURVE_WEIGHTS:
            maps[f"no17+curves {weight}"] = no17_with_curves(pair, hints, curve_only, weight)
    maps["no17, 3 per curve"] = run_no17(pair, Hints(tuple(curves), points_along_curves(pair, curves, 3)), NO17Params())
    maps["no17+indicators"] = no17_with_indicators(pair, hints, curves)
    return maps


def errors(pair, truth, maps, converter):
    out = {}
    for label, fmaps in maps.items():
        for embedding in ("both", "single"):
            result = convert(pair, fmaps, converter, NearestNeighborParams(embedding=embedding))
            out[f"{label} / {embedding}"] = round(score(result, truth)["source_to_target"]["mean_area"], 4)
    return out


def main():
    converter = registry.load("converter", "nearest-neighbor", None)[0]
    rows = []
    for (source, target), count in itertools.product(PAIRS, COUNTS):
        pair, truth = ground_truth_pair(source, target)
        curves = ground_truth_curves(pair.mesh_M, pair.mesh_N, truth, count)
        rows.append(
            {
                "pair": f"{source} -> {target}",
                "curves": count,
                "arc_mismatch": arc_mismatch(pair, truth, curves),
                "errors": errors(pair, truth, candidate_maps(pair, curves), converter),
            }
        )
        print(json.dumps(rows[-1]), file=sys.stderr, flush=True)
    print(
        json.dumps(
            {
                "benchmark": "commutativity",
                "machine": machine(),
                "k": 120,
                "block": BLOCK,
                "k_fit": K_FIT,
                "error": "mean geodesic error / sqrt(area), source -> target",
                "rows": rows,
            },
            indent=1,
        )
    )


if __name__ == "__main__":
    limit_blas_threads()
    main()
