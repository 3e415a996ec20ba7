"""Nearest-neighbour search: approximate search against exact on real spectral embeddings, and its selection.

The embeddings are those a converter searches: data ``Phi_k C_MN^T`` on FAUST tr_reg_000, queries ``Psi_k`` on
tr_reg_011, with ``C_MN`` the functional map of the true correspondence (FAUST's registrations share their
vertices). At 6,890 vertices ``auto`` searches exactly, so the approximate search is forced here.
"""

from __future__ import annotations

import numpy as np
import pytest

from curvefm.errors import InvalidInput
from curvefm.evaluation import ground_truth_for
from curvefm.geometry import load_mesh
from curvefm.pointwise import fmap_from_pointwise, nearest_neighbors, neighbors, uses_approximate
from curvefm.store import Store


@pytest.fixture(scope="module")
def faust_bases(shared_data, tmp_path_factory):
    source, target = shared_data / "faust" / "tr_reg_000.off", shared_data / "faust" / "tr_reg_011.off"
    mesh_M, mesh_N = load_mesh(source), load_mesh(target)
    truth = ground_truth_for(source, target, mesh_M, mesh_N)
    store = Store(tmp_path_factory.mktemp("store"))
    basis_M, basis_N = store.ensure_basis(mesh_M, 120), store.ensure_basis(mesh_N, 120)
    p2p_NM = np.zeros(mesh_N.n_vertices, dtype=np.int64)
    p2p_NM[truth.ids_Y] = truth.ids_X
    return basis_M, basis_N, p2p_NM


def embedding(faust_bases, k: int) -> tuple[np.ndarray, np.ndarray]:
    basis_M, basis_N, p2p_NM = faust_bases
    C_MN = fmap_from_pointwise(p2p_NM, basis_M, basis_N, k, k)
    return basis_M.evecs[:, :k] @ C_MN.T, basis_N.evecs[:, :k]


@pytest.mark.parametrize("k, scan", [(20, False), (120, False), (120, True)])
def test_approximate_search_finds_the_nearest_row_for_99_percent_of_queries(faust_bases, k, scan, monkeypatch):
    data, queries = embedding(faust_bases, k)
    if scan:  # as a scan of a million vertices searches: fewer probed cells
        monkeypatch.setattr(neighbors, "SCAN_ROWS", len(data))
        assert neighbors.probed_cells(len(data)) == neighbors.SCAN_PROBED_CELLS < neighbors.PROBED_CELLS
    exact = nearest_neighbors(data, queries, "exact")
    found = nearest_neighbors(data, queries, "approximate")
    # by distance, in float64: float32 exact search itself misses near-ties, so an index may differ harmlessly
    exact_distance = np.linalg.norm(data[exact] - queries, axis=1)
    found_distance = np.linalg.norm(data[found] - queries, axis=1)
    assert np.mean(found_distance <= exact_distance * (1 + 1e-6)) >= 0.99
    assert np.mean(found == exact) >= 0.98
    assert found_distance.mean() <= 1.01 * exact_distance.mean()


def test_auto_searches_exactly_below_the_threshold_and_approximately_above(faust_bases, monkeypatch):
    data, queries = embedding(faust_bases, 60)
    calls = []
    inverted_file = neighbors._inverted_file_nearest
    monkeypatch.setattr(neighbors, "_inverted_file_nearest", lambda d, q: calls.append(len(d)) or inverted_file(d, q))
    assert not uses_approximate(len(data), len(queries))  # FAUST stays exact by default
    assert np.array_equal(nearest_neighbors(data, queries, "auto"), nearest_neighbors(data, queries, "exact"))
    assert calls == []
    monkeypatch.setattr(neighbors, "APPROXIMATE_FROM_PAIRS", len(data) * len(queries))
    assert uses_approximate(len(data), len(queries)) and not uses_approximate(len(data), len(queries) - 1)
    nearest_neighbors(data, queries, "auto")
    assert calls == [len(data)]


def test_blocked_search_agrees_with_exact(faust_bases):
    data, queries = embedding(faust_bases, 50)
    agree = nearest_neighbors(data, queries[:2000], "blocked") == nearest_neighbors(data, queries[:2000], "exact")
    assert np.mean(agree) >= 0.99


def test_an_unknown_search_is_refused_naming_the_choices():
    with pytest.raises(InvalidInput, match="unknown nearest-neighbour search 'hnsw'.*auto, exact, approximate"):
        nearest_neighbors(np.zeros((5, 3)), np.zeros((2, 3)), "hnsw")


def test_approximate_search_gives_the_same_rows_on_one_thread_and_on_two(faust_bases, monkeypatch):
    data, queries = embedding(faust_bases, 60)
    found = {}
    for threads in ("1", "2"):
        monkeypatch.setenv("CURVEFM_SEARCH_THREADS", threads)
        assert neighbors.search_threads() == int(threads)
        found[threads] = nearest_neighbors(data, queries, "approximate")
    assert np.array_equal(found["1"], found["2"])


@pytest.mark.parametrize("value", ["0", "two", "-1", "1.5"])
def test_a_bad_search_thread_count_is_refused_naming_the_variable(faust_bases, monkeypatch, value):
    monkeypatch.setenv("CURVEFM_SEARCH_THREADS", value)
    data, queries = embedding(faust_bases, 20)
    with pytest.raises(InvalidInput, match=f"CURVEFM_SEARCH_THREADS must be a whole number.*{value!r}"):
        nearest_neighbors(data, queries, "approximate")
