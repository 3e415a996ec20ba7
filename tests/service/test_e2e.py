"""End to end over HTTP, against a real server process: two FAUST shapes, bases from the job queue, a session
with 10 curves, a transfer, a nearest-neighbour refinement; the downloaded maps equal the library's.

Runs twice: with Redis and a real ``curvefm worker`` process, and embedded (no Redis, jobs in the API).
"""

from __future__ import annotations

import io

import numpy as np
import pytest

from curvefm.evaluation import evaluate_map, identity_truth
from curvefm.geometry import farthest_point_sampling, load_mesh
from curvefm.matching import match
from curvefm.session import CurveSpec
from curvefm.store import Store

K = 60
N_CURVES = 10
SHAPES = ("tr_reg_000", "tr_reg_011")


@pytest.fixture(params=["redis", "embedded"])
def mode(request) -> str:
    return request.param


@pytest.fixture
def api(mode, processes, tmp_path, request):
    if mode == "embedded":
        return processes.api(tmp_path / "data")
    redis_url, prefix = request.getfixturevalue("redis_url"), request.getfixturevalue("redis_prefix")
    processes.worker(redis_url, prefix, "w1", tmp_path / "data")
    api = processes.api(tmp_path / "data", redis_url, env={"CURVEFM_QUEUE_PREFIX": prefix})
    api.prefix = prefix
    return api


def download_map(api, link: str) -> np.ndarray:
    return np.loadtxt(io.BytesIO(api.client.get(link).raise_for_status().content), dtype=np.int64)


def test_end_to_end(api, mode, shared_data, tmp_path):
    paths = [shared_data / "faust" / f"{name}.off" for name in SHAPES]
    mesh_M, mesh_N = (load_mesh(path) for path in paths)
    ids = [api.upload(path) for path in paths]
    assert ids == [mesh_M.content_hash, mesh_N.content_hash]

    for shape_id in ids:
        job = api.client.post(f"/shapes/{shape_id}/bases", json={"k": K}).raise_for_status().json()
        info = api.wait_job(job["id"])
        assert info["state"] == "finished", info
        assert info["links"] == {"shape": f"/shapes/{shape_id}"}
        if mode == "redis":
            assert info["worker"].startswith(api.prefix)
        assert any(b["k"] >= K for b in api.client.get(f"/shapes/{shape_id}").json()["bases"])

    session = api.client.post("/sessions", json={"source": ids[0], "target": ids[1], "k": K})
    session = session.raise_for_status().json()
    endpoints = farthest_point_sampling(mesh_M, 2 * N_CURVES).tolist()  # FAUST: internal ids are file ids
    specs = [CurveSpec(source=[a, b], target=[a, b]) for a, b in zip(endpoints[0::2], endpoints[1::2], strict=True)]
    for spec in specs:
        edit = api.client.post(f"/sessions/{session['id']}/curves", json=spec.model_dump())
        edit = edit.raise_for_status().json()
        path = edit["curve"]["path_source"]
        assert (path[0], path[-1]) == tuple(spec.source)
    assert edit["map"]["n_curves"] == N_CURVES

    transfer = api.client.get(f"/sessions/{session['id']}/transfer", params={"function": "uv"}).raise_for_status()
    n, d = (int(x) for x in transfer.headers["X-Shape"].split(","))
    assert (n, d) == (mesh_N.n_vertices, 2)
    assert np.isfinite(np.frombuffer(transfer.content, "<f4")).all()

    job = api.client.post(f"/sessions/{session['id']}/refine", json={"converter": "nearest-neighbor"})
    info = api.wait_job(job.raise_for_status().json()["id"])
    assert info["state"] == "finished", info
    p2p_NM = download_map(api, info["links"]["map_target_to_source.txt"])
    p2p_MN = download_map(api, info["links"]["map_source_to_target.txt"])
    npy = np.load(io.BytesIO(api.client.get(info["links"]["p2p_target_to_source.npy"]).content))
    assert np.array_equal(npy, p2p_NM)

    library = match(mesh_M, mesh_N, specs, k=K, alpha=session["alpha"], store=Store(tmp_path / "data"))
    assert np.mean(p2p_NM == library.maps.p2p_NM) > 0.999
    assert np.mean(p2p_MN == library.maps.p2p_MN) > 0.999
    error = evaluate_map(p2p_NM, identity_truth(mesh_N, mesh_M), mesh_M).mean
    library_error = evaluate_map(library.maps.p2p_NM, identity_truth(mesh_N, mesh_M), mesh_M).mean
    assert error == pytest.approx(library_error, rel=1e-3, abs=1e-6)
    assert error < 0.1, f"mean geodesic error {error:.3f} of the geodesic diameter: the map is poor"
