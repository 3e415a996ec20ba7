"""Curve-constrained functional maps (Gehre et al., SGP 2018), updated incrementally.

``C_MN`` (k x k) maps the coefficients of a function on M (in M's basis) to coefficients on N. It minimises

    E(C) = alpha * ||C Lam_M - Lam_N C||^2  +  sum_l (w_l / W) * (1 / s) * ||PsiBar_l C - PhiBar_l||^2

with ``PhiBar_l = P_l Phi`` (s x k) the basis of M restricted to the l-th curve's s uniform samples and
``PsiBar_l`` the same on N. Normalisation, so one ``alpha`` serves every pair:

* bases are those of the meshes scaled to unit area (see :mod:`curvefm.spectral.basis`): invariant to mesh scale;
* each curve's term is a mean over its samples (1/s): invariant to samples per curve;
* curve weights are divided by their sum ``W``: invariant to the number of curves;
* eigenvalues are divided by ``max(lam_M[k-1], lam_N[k-1])``, so the commutativity term is O(1) for any k.

Because ``Lam`` is diagonal, E separates by columns: column j of C solves the k x k system
``(G + alpha * diag((lam^N_i - lam^M_j)^2)) c_j = B[:, j]`` with ``G = sum_l w~_l PsiBar_l^T PsiBar_l`` and
``B = sum_l w~_l PsiBar_l^T PhiBar_l``. The solver keeps the weighted sums of the curves' k x k products, so adding,
editing or removing a curve adds or subtracts one curve's products before the k small solves
(:mod:`curvefm.fmap.column_solve`). A curve itself is kept as its two vertex paths (int32) and its weight: its
products are computed again from the paths when it is removed or replaced (well under a millisecond at k = 120), so a
stored curve costs a few bytes per path vertex instead of three k x k matrices (346 kB at k = 120).
``C_NM`` is the same problem with the roles of M and N exchanged; both are solved side by side on two threads,
or, for a server, each when first read after an edit (``interactive``).

The source side's factor of a curve (its restricted basis, scaled) depends only on M, its basis and the path, so it
is cached by content (:data:`SOURCE_FACTORS`): a collection's members all share the template as their source, and
every member's solver reuses the template curves' factors instead of restricting the template's basis again.
"""

from __future__ import annotations

import hashlib
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from concurrent.futures import Executor, ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from curvefm.cache import LRU
from curvefm.errors import Conflict, InvalidInput, NotFound
from curvefm.fmap.column_solve import Prior, parallel_pays_off, solve_both, solve_columns
from curvefm.fmap.maps import EffectiveSolve
from curvefm.fmap.restriction import DEFAULT_SAMPLES, restrict
from curvefm.spectral import DEFAULT_K, Basis

DEFAULT_ALPHA = 100.0  # chosen in docs/decisions.md#choosing-alpha (experiments/alpha.py)
RESUM_AFTER = 1e4
"""Subtracting a curve's products leaves rounding of about 1e-16 of its weight in the sums; once the weight
removed since they were last summed exactly exceeds this many times the weight held, they are summed again
(so the relative rounding stays below about 1e-12, whatever the weights: a curve of weight 1e12 added and
removed again would otherwise change the map by 0.2%)."""
SOURCE_FACTORS: LRU[np.ndarray] = LRU(256)
"""Source-side curve factors (read-only arrays) by (solver kind and parameters, mesh and basis digest, path, samples):
at k = 120 and 100 samples one is 96 kB (combined: 134 kB), so the cache holds at most about 35 MB."""

CurveTuple = tuple[ArrayLike, ArrayLike, float]
"""A curve as ``(path_M, path_N, weight)``: vertex paths (internal ids) on each shape and the curve's weight."""


@dataclass(frozen=True)
class CurveTerm:
    """One curve as the solver keeps it: its vertex paths (internal ids, int32) and its weight."""

    path_M: np.ndarray
    path_N: np.ndarray
    weight: float

    def same_as(self, other: CurveTerm) -> bool:
        return (
            self.weight == other.weight
            and np.array_equal(self.path_M, other.path_M)
            and np.array_equal(self.path_N, other.path_N)
        )


def cross_products(X: np.ndarray, Y: np.ndarray) -> np.ndarray:
    """``[X^T X, Y^T Y, Y^T X]`` (3 x k x k) for factors ``X`` (on M) and ``Y`` (on N) with the same rows."""
    k = X.shape[1]
    products = np.empty((3, k, k))
    np.matmul(X.T, X, out=products[0])
    np.matmul(Y.T, Y, out=products[1])
    np.matmul(Y.T, X, out=products[2])
    return products


class CurveMapSolver:
    """Built once per shape pair; each curve edit returns the new ``C_MN`` and ``C_NM``.

    >>> with CurveMapSolver(vertices_M, basis_M, vertices_N, basis_N, k=120) as solver:
    ...     cid = solver.add_curve(path_M, path_N)          # vertex paths, internal ids
    ...     C_MN, C_NM = solver.C_MN, solver.C_NM

    Curve ids: give your own (``curve_id=``) or let the solver name the curve ``c1``, ``c2``, ... (an automatic
    id skips those in use; an explicit id in use is a conflict). Removed ids are not handed out again.

    ``interactive=True``: an edit only updates the curve terms; each map is solved on the calling thread when
    first read after it (once per edit, however often it is read; :attr:`last_solve_ms` says how long that
    took). The web UI reads ``C_MN`` (the texture) after every edit and ``C_NM`` rarely; a script adding ten
    curves before reading pays for one solve, not ten; a server sharing its cores between many sessions
    spends them on the maps someone looks at.

    ``executor``: where the reverse map is solved while the calling thread solves ``C_MN`` (not interactive).
    Without one, the solver starts its own single thread when first needed and stops it on :meth:`close`
    (or at the end of a ``with`` block); an executor handed in is left to its owner.
    """

    PRODUCTS = 3  # k x k products per curve (:meth:`_products`) that the solver keeps summed

    def __init__(
        self,
        vertices_M: np.ndarray,
        basis_M: Basis,
        vertices_N: np.ndarray,
        basis_N: Basis,
        k: int = DEFAULT_K,
        alpha: float = DEFAULT_ALPHA,
        samples: int = DEFAULT_SAMPLES,
        interactive: bool = False,
        executor: Executor | None = None,
    ):
        if k > min(basis_M.k, basis_N.k):
            raise InvalidInput(f"k = {k} exceeds the computed bases (M has {basis_M.k}, N has {basis_N.k})")
        self.k, self.alpha, self.samples, self.interactive = k, float(alpha), samples, interactive
        self.vertices_M, self.vertices_N = vertices_M, vertices_N
        self.basis_M, self.basis_N = basis_M.truncated(k), basis_N.truncated(k)
        self._source_digest = shape_digest(vertices_M, self.basis_M)
        scale = max(self.basis_M.evals[-1], self.basis_N.evals[-1], 1e-12)
        self.lam_M, self.lam_N = self.basis_M.evals / scale, self.basis_N.evals / scale
        self.curves: dict[str, CurveTerm] = {}
        self._sums = np.zeros((self.PRODUCTS, k, k))  # sum over curves of weight * _products(curve)
        self._removed_weight = 0.0  # subtracted from _sums since they were last summed exactly
        self._next_number = 1  # of the next automatic id, c<number>
        self._C_MN, self._C_NM = np.zeros((k, k)), np.zeros((k, k))
        self._stale: set[str] = set()  # the maps ("MN", "NM") not yet solved for the current curves
        self.last_solve_ms = 0.0
        self._executor, self._owns_executor = executor, False

    # -- editing ----------------------------------------------------------------------------------------
    def add_curve(self, path_M: ArrayLike, path_N: ArrayLike, weight: float = 1.0, curve_id: str | None = None) -> str:
        """Add one curve pair (vertex paths, internal ids); returns its id (``curve_id``, or an automatic one)."""
        return self.add_curves([(path_M, path_N, weight)], ids=[curve_id])[0]

    def add_curves(self, curves: Iterable[CurveTuple], ids: Sequence[str | None] | None = None) -> list[str]:
        """Add several ``(path_M, path_N, weight)`` curves with a single solve; returns their ids.

        ``ids``: one per curve, an explicit id or ``None`` for an automatic one (all automatic when omitted).
        Nothing is added if any curve or id is rejected, or the solve fails.
        """
        curves = list(curves)
        ids = [None] * len(curves) if ids is None else list(ids)
        if len(ids) != len(curves):
            raise InvalidInput(f"{len(curves)} curves but {len(ids)} ids; give one id (or None) per curve")
        terms = [self._term(path_M, path_N, weight) for path_M, path_N, weight in curves]
        added = sum((term.weight * self._products(term) for term in terms), np.zeros_like(self._sums))
        chosen = self._claim_ids(ids)
        self._apply({**self.curves, **dict(zip(chosen, terms, strict=True))}, self._sums + added, self._removed_weight)
        return chosen

    def replace_curve(self, curve_id: str, path_M: ArrayLike, path_N: ArrayLike, weight: float = 1.0) -> None:
        self._require(curve_id)
        self.sync({**self.curves, curve_id: self._term(path_M, path_N, weight)})

    def remove_curve(self, curve_id: str) -> None:
        self._require(curve_id)
        self.sync({other: term for other, term in self.curves.items() if other != curve_id})

    def sync(self, curves: Mapping[str, CurveTerm | CurveTuple]) -> None:
        """Hold exactly ``curves`` (id -> :class:`CurveTerm` or ``(path_M, path_N, weight)``), with one solve.

        Curves not given are removed, new and changed ones added; unchanged ones cost nothing. This is how a
        process brings its solver up to date with a session that another process has edited. If the solve fails
        the solver keeps its curves and maps.
        """
        wanted = {curve_id: _as_term(self._term, curve) for curve_id, curve in curves.items()}
        every = [*self.curves, *(curve_id for curve_id in wanted if curve_id not in self.curves)]
        changed = [cid for cid in every if not _same(self.curves.get(cid), wanted.get(cid))]
        delta, removed = np.zeros_like(self._sums), 0.0
        for curve_id in changed:
            if (new := wanted.get(curve_id)) is not None:
                delta += new.weight * self._products(new)
            if (old := self.curves.get(curve_id)) is not None:
                delta -= old.weight * self._products(old)
                removed += old.weight
        if not changed:
            return
        sums, removed = self._sums + delta, self._removed_weight + removed
        if removed > RESUM_AFTER * sum(term.weight for term in wanted.values()):
            sums, removed = sum((t.weight * self._products(t) for t in wanted.values()), np.zeros_like(sums)), 0.0
        self._apply(wanted, sums, removed)

    def _apply(self, curves: dict[str, CurveTerm], sums: np.ndarray, removed_weight: float) -> None:
        """Make ``curves`` (with the sums of their products) the solver's and solve (an interactive solver: when
        read); if the solve fails, the previous curves and maps stay."""
        previous = self.curves, self._sums, self._removed_weight
        self.curves, self._sums, self._removed_weight = curves, sums, removed_weight
        try:
            self._solve()
        except BaseException:
            self.curves, self._sums, self._removed_weight = previous
            raise

    def _claim_ids(self, requested: list[str | None]) -> list[str]:
        """The requested ids with automatic ones filled in; explicit ids are checked before any is claimed."""
        taken = set(self.curves)
        for curve_id in requested:
            if curve_id is None:
                continue
            if not isinstance(curve_id, str) or not curve_id:
                raise InvalidInput(f"a curve id must be a non-empty string, got {curve_id!r}")
            if curve_id in taken:
                raise Conflict(f"curve id '{curve_id}' already exists")
            taken.add(curve_id)
        return [self._automatic_id(taken) if curve_id is None else curve_id for curve_id in requested]

    def _automatic_id(self, taken: set[str]) -> str:
        while f"c{self._next_number}" in taken:
            self._next_number += 1
        curve_id = f"c{self._next_number}"
        self._next_number += 1
        taken.add(curve_id)
        return curve_id

    def _require(self, curve_id: str) -> None:
        if curve_id not in self.curves:
            raise NotFound(f"no curve '{curve_id}' in this solver")

    def _term(self, path_M: ArrayLike, path_N: ArrayLike, weight: float) -> CurveTerm:
        if not weight > 0 or not np.isfinite(weight):
            raise InvalidInput(f"curve weight must be a positive number, got {weight}")
        return CurveTerm(_compact(path_M, len(self.vertices_M)), _compact(path_N, len(self.vertices_N)), float(weight))

    def _products(self, term: CurveTerm) -> np.ndarray:
        """The curve's :func:`cross_products` (``PRODUCTS`` x k x k) of its :meth:`_factors`."""
        return cross_products(*self._factors(term))

    def _factors(self, term: CurveTerm) -> tuple[np.ndarray, np.ndarray]:
        """``(X, Y)``, each side's :meth:`_side_factor`; the source's from :data:`SOURCE_FACTORS` when there."""
        key = (type(self).__name__, self._factor_params(), self._source_digest, term.path_M.tobytes(), self.samples)
        X = SOURCE_FACTORS.get(key, lambda: _read_only(self._side_factor("M", term.path_M)))
        return X, self._side_factor("N", term.path_N)

    def _side_factor(self, side: str, path: np.ndarray) -> np.ndarray:
        """``PhiBar / sqrt(s)`` on M (``side="M"``) or ``PsiBar / sqrt(s)`` on N: the curve terms are
        ``||PsiBar C - PhiBar||^2 / s``."""
        return self._restricted(side, path) * (1.0 / np.sqrt(self.samples))

    def _restricted(self, side: str, path: np.ndarray) -> np.ndarray:
        """The basis of ``side`` (``M`` or ``N``) at the curve's uniform samples (s x k)."""
        vertices, basis = (self.vertices_M, self.basis_M) if side == "M" else (self.vertices_N, self.basis_N)
        return restrict(vertices, path, basis.evecs, self.samples)

    def _factor_params(self) -> tuple[Any, ...]:
        """What besides the shape, path and samples a side's factor depends on (a subclass's energy parameters)."""
        return ()

    # -- solving ----------------------------------------------------------------------------------------
    @property
    def commutativity_weight(self) -> float:
        """The ``alpha`` the maps are solved with now."""
        return self.alpha

    def normal_equations(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(G_M, G_N, B)`` summed over curves with normalised weights (B: rows N, columns M)."""
        total = sum(term.weight for term in self.curves.values()) or 1.0
        return self._weighted(self._sums / total)

    def _weighted(self, mean_products: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(G_M, G_N, B)`` from the curves' mean :meth:`_products` (a subclass weighs its terms here)."""
        G_M, G_N, B = mean_products
        return G_M, G_N, B

    def _solve(self) -> None:
        if not self.curves:
            self._sums, self._removed_weight = np.zeros_like(self._sums), 0.0  # exact zeros, no rounding left
            self._C_MN, self._C_NM = np.zeros((self.k, self.k)), np.zeros((self.k, self.k))
            self._stale = set()
        elif self.interactive:
            self._stale = {"MN", "NM"}
        else:
            G_M, G_N, B = self.normal_equations()
            executor = self._solve_executor(B.size)
            started = time.perf_counter()
            priors = self._priors()
            C_MN, C_NM = solve_both(
                G_N, G_M, B, self.lam_N, self.lam_M, self.commutativity_weight, priors=priors, executor=executor
            )
            self._C_MN, self._C_NM = self._sized(C_MN), self._sized(C_NM)
            self._stale, self.last_solve_ms = set(), _ms_since(started)

    def _solve_executor(self, size: int) -> Executor | None:
        """The executor for the reverse map, started on first need when the solver owns it."""
        if self._executor is None and parallel_pays_off(size):
            self._executor = ThreadPoolExecutor(1, thread_name_prefix="curvefm-columns")
            self._owns_executor = True
        return self._executor

    @property
    def pending(self) -> frozenset[str]:
        """The maps (``"MN"``, ``"NM"``) an interactive solver has still to solve for its current curves."""
        return frozenset(self._stale)

    @property
    def C_MN(self) -> np.ndarray:
        """The map from M to N (with ``interactive``, solved on first use after an edit)."""
        if "MN" in self._stale:
            G_M, G_N, B = self.normal_equations()
            self._C_MN = self._sized(self._solve_one(G_N, B, self.lam_N, self.lam_M, self._priors()[0]))
            self._stale.discard("MN")
        return self._C_MN

    @property
    def C_NM(self) -> np.ndarray:
        """The reverse map (with ``interactive``, solved on first use after an edit)."""
        if "NM" in self._stale:
            G_M, G_N, B = self.normal_equations()
            self._C_NM = self._sized(self._solve_one(G_M, B.T, self.lam_M, self.lam_N, self._priors()[1]))
            self._stale.discard("NM")
        return self._C_NM

    def _solve_one(
        self, G: np.ndarray, B: np.ndarray, lam_rows: np.ndarray, lam_cols: np.ndarray, prior: Prior | None
    ) -> np.ndarray:
        started = time.perf_counter()
        C = solve_columns(G, B, lam_rows, lam_cols, self.commutativity_weight, prior=prior)
        self.last_solve_ms = _ms_since(started)
        return C

    @property
    def prior_pending(self) -> bool:
        """Whether the maps will still change without an edit (a prior being computed): never here."""
        return False

    def settle(self) -> None:
        """Finish what the maps still wait for (nothing here), so that they are final for the current curves."""

    def _priors(self) -> tuple[Prior | None, Prior | None]:
        """Maps the solutions (``C_MN``, ``C_NM``) are pulled towards: none in the paper's energy."""
        return None, None

    def _sized(self, C: np.ndarray) -> np.ndarray:
        """The solved map as the solver hands it out: the whole k x k map in the paper's energy."""
        return C

    def effective(self) -> EffectiveSolve:
        """The energy, weights and size of the maps as they are solved and handed out now: the paper's curve
        energy, the whole k x k map with the solver's ``alpha``."""
        k, alpha = self.k, self.commutativity_weight
        return EffectiveSolve(
            "curves", {"alpha": alpha}, k, f"curves; {k} x {k}", f"the curve energy at k = {k} with alpha {alpha:g}"
        )

    def energy(self, C_MN: np.ndarray) -> float:
        """E(C_MN) up to the constant sum_l w~_l ||PhiBar_l||^2 / s (so it may be negative)."""
        _, G_N, B = self.normal_equations()
        D = (self.lam_N[:, None] - self.lam_M[None, :]) ** 2
        commutativity = self.commutativity_weight * np.sum(D * C_MN**2)
        return float(commutativity + np.sum(C_MN * (G_N @ C_MN)) - 2 * np.sum(C_MN * B))

    # -- lifetime ---------------------------------------------------------------------------------------
    def close(self) -> None:
        """Stop the thread the solver started for itself, if any (it starts again when needed)."""
        if self._owns_executor and self._executor is not None:
            self._executor.shutdown()
            self._executor, self._owns_executor = None, False

    def __enter__(self) -> CurveMapSolver:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()


def _ms_since(started: float) -> float:
    return round((time.perf_counter() - started) * 1000, 3)


def shape_digest(vertices: np.ndarray, basis: Basis) -> bytes:
    """A digest of a mesh's vertices and its basis (eigenvalues, the first rows of the eigenvectors, the shape):
    equal for the same shape and basis, whichever process loaded them."""
    digest = hashlib.blake2b(np.ascontiguousarray(vertices).tobytes(), digest_size=16)
    digest.update(basis_digest(basis))
    return digest.digest()


def basis_digest(basis: Basis) -> bytes:
    digest = hashlib.blake2b(basis.evals.tobytes(), digest_size=16)
    digest.update(np.ascontiguousarray(basis.evecs[:8]).tobytes())
    digest.update(str(basis.evecs.shape).encode())
    return digest.digest()


def _read_only(array: np.ndarray) -> np.ndarray:
    array.flags.writeable = False
    return array


def _compact(path: ArrayLike, n_vertices: int) -> np.ndarray:
    """A vertex path as int32 (internal ids), checked against the mesh's ``n_vertices``."""
    path = np.asarray(path, dtype=np.int64)
    if path.size and (path.min() < 0 or path.max() >= n_vertices):
        raise InvalidInput(f"a curve path has a vertex outside 0..{n_vertices - 1}")
    return path.astype(np.int32)


def _as_term(make: Callable[..., CurveTerm], curve: CurveTerm | CurveTuple) -> CurveTerm:
    return curve if isinstance(curve, CurveTerm) else make(*curve)


def _same(a: CurveTerm | None, b: CurveTerm | None) -> bool:
    return a is b or (a is not None and b is not None and a.same_as(b))
