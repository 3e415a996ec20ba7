"""Exports a lab uses: both functional maps (and, after a refinement, the pointwise maps) as a MATLAB .mat, and the
textured target as OBJ + MTL + texture image in one zip; from the library, the API (live and as refinement
results), the Python client and the web UI's links."""

from __future__ import annotations

import io
import zipfile
from pathlib import Path

import numpy as np
import pytest
import scipy.io
from PIL import Image
from support.morphometrics import read_tps
from support.ui import VIEWPORT, open_session

from curvefm.client import Client
from curvefm.geometry import checkerboard_image, load_mesh, save_textured_zip
from curvefm.matching import save_maps_mat
from curvefm.service.demo import demo_shapes

K = 20
CURVES = [{"source": [10, 2000], "target": [10, 2000]}, {"source": [500, 3500], "target": [500, 3500]}]
ZIPPED = {"target_textured.obj", "target_textured.mtl", "target_textured.png"}
NAME = "demo -> deformed / try 1"
SAFE_NAME = "demo-deformed-try-1"  # the session's name as download names carry it


def saved_as(answer) -> str:
    """The file name a download's Content-Disposition gives."""
    disposition = answer.headers["content-disposition"]
    assert disposition.startswith('attachment; filename="'), disposition
    return disposition.removeprefix('attachment; filename="').removesuffix('"')


def unzipped_mesh(data: bytes, folder: Path):
    """The OBJ of a textured zip, read by curvefm's own reader (which follows its MTL to the image)."""
    with zipfile.ZipFile(io.BytesIO(data)) as archive:
        assert set(archive.namelist()) == ZIPPED
        archive.extractall(folder)
    return load_mesh(folder / "target_textured.obj")


def test_the_mat_file_holds_the_maps_as_matlab_reads_them(tmp_path):
    rng = np.random.default_rng(0)
    C_MN, C_NM, p2p = rng.normal(size=(7, 7)), rng.normal(size=(7, 7)), rng.integers(-1, 100, 50)
    save_maps_mat(tmp_path / "maps.mat", C_MN, C_NM, map_target_to_source=p2p)
    loaded = scipy.io.loadmat(tmp_path / "maps.mat")
    assert np.array_equal(loaded["C_source_to_target"], C_MN) and np.array_equal(loaded["C_target_to_source"], C_NM)
    assert np.array_equal(loaded["map_target_to_source"].ravel(), p2p)
    note = str(loaded["note"])
    assert "0-based" in note and "C_source_to_target (7 x 7)" in note and "No pointwise maps" not in note
    save_maps_mat(tmp_path / "live.mat", C_MN[:5, :5], C_NM[:5, :5], "Live.")
    note = str(scipy.io.loadmat(tmp_path / "live.mat")["note"][0])
    assert note.startswith("Live. C_source_to_target (5 x 5)") and "map_target_to_source" not in note
    assert "No pointwise maps" in note


def test_the_textured_zip_opens_as_a_textured_mesh(tmp_path):
    mesh = demo_shapes()[1]
    uv = np.random.default_rng(1).random((mesh.n_vertices, 2))
    save_textured_zip(mesh, uv, tmp_path / "t.zip", "target_textured")
    loaded = unzipped_mesh((tmp_path / "t.zip").read_bytes(), tmp_path / "out")
    assert np.allclose(loaded.vertices, mesh.vertices) and np.array_equal(loaded.faces, mesh.faces)
    assert np.allclose(loaded.uv, uv, atol=1e-8)
    assert loaded.texture_path is not None and Path(loaded.texture_path).name == "target_textured.png"
    assert np.array_equal(np.asarray(Image.open(loaded.texture_path)), checkerboard_image())


@pytest.fixture(scope="module")
def served(module_processes, tmp_path_factory):
    api = module_processes.api(tmp_path_factory.mktemp("exports") / "data")
    shapes, _ = api.demo_pair(tmp_path_factory.mktemp("shapes"), K)
    body = {"source": shapes[0], "target": shapes[1], "k": K, "name": NAME}
    session_id = api.client.post("/sessions", json=body).raise_for_status().json()["id"]
    for curve in CURVES:
        api.client.post(f"/sessions/{session_id}/curves", json=curve).raise_for_status()
    return api, session_id


def test_the_live_exports_are_the_live_map(served, tmp_path):
    api, session_id = served
    base = f"/sessions/{session_id}/exports"
    answer = api.client.get(f"{base}/maps.mat").raise_for_status()
    served_map = api.client.get(f"/sessions/{session_id}/map").json()
    loaded = scipy.io.loadmat(io.BytesIO(answer.content))
    assert answer.headers["content-type"] == "application/x-matlab-data"
    revision = served_map["revision"]
    assert answer.headers["x-revision"] == str(revision)
    assert saved_as(answer) == f"{SAFE_NAME}_{session_id}_live_r{revision}_maps.mat"
    assert np.array_equal(loaded["C_source_to_target"], np.array(served_map["C_source_to_target"]))
    assert np.array_equal(loaded["C_target_to_source"], np.array(served_map["C_target_to_source"]))
    note = str(loaded["note"])
    assert f"Session '{NAME}' ({session_id}) at revision {revision}: its live functional maps" in note
    assert served_map["solve"]["summary"] in note and f"({K} x {K})" in note and "No pointwise maps" in note

    answer = api.client.get(f"{base}/C_source_to_target.npy").raise_for_status()
    assert np.array_equal(np.load(io.BytesIO(answer.content)), np.array(served_map["C_source_to_target"]))
    assert saved_as(answer) == f"{SAFE_NAME}_{session_id}_live_r{revision}_C_source_to_target.npy"

    answer = api.client.get(f"{base}/target_textured.zip").raise_for_status()
    transfer = api.client.get(f"/sessions/{session_id}/transfer", params={"function": "uv"})
    uv = np.frombuffer(transfer.content, dtype="<f4").reshape(-1, 2)
    mesh = unzipped_mesh(answer.content, tmp_path)
    assert answer.headers["content-type"] == "application/zip"
    assert mesh.n_vertices == len(uv) and np.allclose(mesh.uv, uv, atol=1e-6)
    assert api.client.get(f"{base}/maps.npy").status_code == 422


def test_a_refinement_writes_both_exports_with_its_pointwise_maps(served, tmp_path):
    api, session_id = served
    with Client(api.url, token=api.token) as client:
        r = client.open_session(session_id).refine("nearest-neighbor").wait(progress=False)
        mat = scipy.io.loadmat(io.BytesIO(client.download(r.files["maps.mat"])))
        textured = client.download(r.files["target_textured.zip"])
    assert np.array_equal(mat["map_target_to_source"].ravel(), r.map_target_to_source)
    assert np.array_equal(mat["map_source_to_target"].ravel(), r.map_source_to_target)
    assert mat["C_source_to_target"].shape == (K, K)
    assert unzipped_mesh(textured, tmp_path).uv is not None
    note = str(mat["note"])
    assert f"Session '{NAME}' ({session_id}) at revision {r.revision}, refined by 'nearest-neighbor'" in note
    assert f"the functional maps as solved, {K} x {K}" in note and "map_target_to_source(j + 1)" in note
    for name in ("maps.mat", "C_source_to_target.npy", "map_target_to_source.txt"):
        answer = api.client.get(f"/jobs/{r.job_id}/files/{name}").raise_for_status()
        assert saved_as(answer) == f"{SAFE_NAME}_{session_id}_nearest-neighbor_r{r.revision}_{name}"


def test_a_zoomout_refinement_exports_its_refined_functional_maps_at_k_final(served):
    """ZoomOut's C files and .mat hold the maps it fitted at k_final, not the live K x K map they started from,
    under names that say the converter."""
    api, session_id = served
    k_final = 2 * K
    with Client(api.url, token=api.token) as client:
        r = client.open_session(session_id).refine("zoomout", k_init=K, k_final=k_final).wait(progress=False)
        mat = scipy.io.loadmat(io.BytesIO(client.download(r.files["maps.mat"])))
        live = client.open_session(session_id).map()
    assert r.result["kept"] == "refined", r.result["reason"]
    assert r.result["functional_maps"]["size"] == [k_final, k_final]
    assert r.C_source_to_target.shape == r.C_target_to_source.shape == (k_final, k_final)
    assert live.shape == (K, K) and not np.allclose(r.C_source_to_target[:K, :K], live)
    assert np.array_equal(mat["C_source_to_target"], r.C_source_to_target)
    assert f"induce at the converter's size, {k_final} x {k_final}" in str(mat["note"])
    answer = api.client.get(f"/jobs/{r.job_id}/files/C_source_to_target.npy").raise_for_status()
    assert saved_as(answer) == f"{SAFE_NAME}_{session_id}_zoomout_r{r.revision}_C_source_to_target.npy"


def test_the_ui_links_download_the_live_exports(served, browser, tmp_path):
    api, session_id = served
    context = browser.new_context(viewport=VIEWPORT, accept_downloads=True)
    page = context.new_page()
    open_session(page, api.url, session_id, token=api.token)
    with page.expect_download() as download:
        page.click("#download-mat")
    loaded = scipy.io.loadmat(download.value.path())
    name = download.value.suggested_filename
    with page.expect_download() as download:
        page.click("#download-textured")
    mesh = unzipped_mesh(Path(download.value.path()).read_bytes(), tmp_path)
    with page.expect_download() as download:
        page.click("#download-tps")
    specimens = read_tps(Path(download.value.path()).read_text())
    tps_name = download.value.suggested_filename
    context.close()
    served_map = api.client.get(f"/sessions/{session_id}/map").json()
    assert np.array_equal(loaded["C_source_to_target"], np.array(served_map["C_source_to_target"]))
    assert name == f"{SAFE_NAME}_{session_id}_live_r{served_map['revision']}_maps.mat"
    assert mesh.n_vertices == demo_shapes()[1].n_vertices
    assert tps_name == f"{SAFE_NAME}_{session_id}_live_r{served_map['revision']}_landmarks.tps"
    assert [len(points) for _, points in specimens] == [len(CURVES) * 22] * 2  # 2 ends + 20 semilandmarks a curve
