"""Nearest neighbours in high dimension (spectral embeddings: 20-240 dimensions), exact or approximate.

Trees are useless at this dimension (cKDTree: 156 s for 30k x 30k in 120 dimensions here). Exact search is
faiss's ``IndexFlatL2`` (2.7 s there), or blocked float32 matrix products in numpy (3.4 s) as the
dependency-free path. Its cost grows with data rows x queries, so at scan resolution (110k-440k vertices a
shape) it dominates: about 16 times the 110k cost at 440k.

Approximate search is faiss's inverted file (``IndexIVFFlat``): k-means cells over the data, each query
compares against the points of the ``nprobe`` nearest cells only. Spectral embeddings of a surface lie near
a two-dimensional manifold, so a few cells hold every near neighbour. Measured on FAUST subdivided to 28k /
110k / 440k vertices in 20, 60 and 120 dimensions (``benchmarks/bench_neighbors.py``, 2026-11-23): 2 sqrt(n)
cells and 8 probed give the exact nearest distance for >= 99.65% of queries, mean distance +4e-5 at most,
4-150x faster than exact search (110k, 120 dimensions: 4.5 s against 47 s; in 20 and 60 dimensions exact
search is bound by memory traffic and its times varied up to 18x between runs). HNSW (``IndexHNSWFlat``, 32
links) lost on these data: at efSearch 256 below 99% in 7 of the 9 cases (83-98%), and 1.4-4x slower than IVF
at efSearch 64.

Recall is measured against exact search by distance, not by index: float32 exact search expands
``|q - d|^2 = |q|^2 - 2 q.d + |d|^2``, and on subdivided meshes (near-duplicate embedding rows) it misses the
true nearest row for up to 2% of queries (440k, 120 dimensions); each such "mismatch" of IVF seen in the
benchmark was a row no farther, in float64, than the one exact search returned.

Exact search runs as many OpenMP threads as the process allows (``OMP_NUM_THREADS``, which
:func:`curvefm.runtime.limit_blas_threads` sets to one for the CLI, workers and benchmarks). Approximate search,
which only big meshes reach and which then takes tens of seconds, uses ``CURVEFM_SEARCH_THREADS`` threads (default:
every core the process may run on): at 440k vertices in 240 dimensions one search took 76 s on one core and 49 s
on two beside other work (2026-11-23).
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Literal

import numpy as np

from curvefm.errors import InvalidInput

BLOCK = 4096
Search = Literal["auto", "exact", "approximate", "blocked"]
SEARCHES: tuple[str, ...] = ("auto", "exact", "approximate", "blocked")
#: ``auto`` searches approximately from this many data rows x queries on: about 1 s of exact search here
#: (120 dimensions, one core); FAUST (6,890 x 6,890) and a few thousand ZoomOut samples stay exact.
# chosen in docs/decisions.md#nearest-neighbour-search
APPROXIMATE_FROM_PAIRS = 200_000_000
CELLS_PER_SQRT_ROW = 2  # k-means cells: 2 sqrt(rows) (664 at 110k, 1,328 at 440k)
TRAINING_ROWS_PER_CELL = 40  # faiss asks for at least 39 points a cell
PROBED_CELLS = 8  # cells each query searches
# chosen in docs/decisions.md#nearest-neighbour-search
SCAN_ROWS = 1_000_000
"""From this many data rows on (scans of a million vertices and more) each query searches
:data:`SCAN_PROBED_CELLS` cells: a search's cost grows as rows^1.5 at a fixed number of probes."""
SCAN_PROBED_CELLS = 4
#: k-means iterations to place the cells (faiss's default is 25): at 440k x 240 dimensions 10 gave the same
#: neighbour for every query as 25, in 12 s of training instead of 34 (2026-11-23)
KMEANS_ITERATIONS = 10


def nearest_neighbors(data: np.ndarray, queries: np.ndarray, search: str = "auto") -> np.ndarray:
    """For each row of ``queries``, the index of the nearest row of ``data`` (Euclidean).

    ``search``: ``exact`` (faiss ``IndexFlatL2``), ``blocked`` (exact, numpy only), ``approximate`` (faiss
    IVF, recall >= 99%), or ``auto``: exact below :data:`APPROXIMATE_FROM_PAIRS` data rows x queries,
    approximate from there on."""
    if search not in SEARCHES:
        raise InvalidInput(f"unknown nearest-neighbour search {search!r}; searches are {', '.join(SEARCHES)}")
    data = np.ascontiguousarray(data, dtype=np.float32)
    queries = np.ascontiguousarray(queries, dtype=np.float32)
    if search == "blocked":
        return _blocked_nearest(data, queries)
    if search == "approximate" or (search == "auto" and uses_approximate(len(data), len(queries))):
        return _inverted_file_nearest(data, queries)
    import faiss

    index = faiss.IndexFlatL2(data.shape[1])
    index.add(data)
    return index.search(queries, 1)[1][:, 0].astype(np.int64)


def uses_approximate(rows: int, queries: int) -> bool:
    """Whether ``auto`` searches ``rows`` data rows for ``queries`` queries approximately."""
    return rows * queries >= APPROXIMATE_FROM_PAIRS


def cell_count(rows: int) -> int:
    """k-means cells of the inverted file for ``rows`` data rows (enough training points for each)."""
    return max(1, min(round(CELLS_PER_SQRT_ROW * np.sqrt(rows)), rows // TRAINING_ROWS_PER_CELL))


def probed_cells(rows: int) -> int:
    """Cells each query of an approximate search over ``rows`` data rows searches."""
    return SCAN_PROBED_CELLS if rows >= SCAN_ROWS else PROBED_CELLS


def search_threads() -> int:
    """Threads for an approximate search: ``CURVEFM_SEARCH_THREADS``, default every core this process may use."""
    value = os.environ.get("CURVEFM_SEARCH_THREADS", "")
    if not value:
        return len(os.sched_getaffinity(0))
    if not value.isdigit() or int(value) < 1:
        raise InvalidInput(f"CURVEFM_SEARCH_THREADS must be a whole number of threads >= 1, got {value!r}")
    return int(value)


@contextmanager
def _faiss_threads(threads: int) -> Iterator[None]:
    import faiss

    before = faiss.omp_get_max_threads()
    faiss.omp_set_num_threads(threads)
    try:
        yield
    finally:
        faiss.omp_set_num_threads(before)


def _inverted_file_nearest(data: np.ndarray, queries: np.ndarray) -> np.ndarray:
    with _faiss_threads(search_threads()):
        return _inverted_file_search(data, queries)


def _inverted_file_search(data: np.ndarray, queries: np.ndarray) -> np.ndarray:
    import faiss

    cells = cell_count(len(data))
    quantizer = faiss.IndexFlatL2(data.shape[1])
    index = faiss.IndexIVFFlat(quantizer, data.shape[1], cells)
    index.cp.niter = KMEANS_ITERATIONS
    training = min(len(data), TRAINING_ROWS_PER_CELL * cells)
    index.train(data[np.random.default_rng(0).choice(len(data), training, replace=False)])
    index.add(data)
    index.nprobe = min(probed_cells(len(data)), cells)
    return index.search(queries, 1)[1][:, 0].astype(np.int64)


def _blocked_nearest(data: np.ndarray, queries: np.ndarray) -> np.ndarray:
    # |q - d|^2 = |q|^2 - 2 q.d + |d|^2; |q|^2 does not change the argmin
    data_sq = np.einsum("ij,ij->i", data, data)
    out = np.empty(len(queries), dtype=np.int64)
    for start in range(0, len(queries), BLOCK):
        block = queries[start : start + BLOCK]
        out[start : start + BLOCK] = np.argmin(data_sq[None, :] - 2.0 * (block @ data.T), axis=1)
    return out
