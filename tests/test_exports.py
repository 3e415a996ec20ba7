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
from ui_helpers import VIEWPORT, open_session

from curvefm.client import Client
from curvefm.geometry import checkerboard_image, load_mesh, save_textured_zip
from curvefm.matching import save_maps_mat
from curvefm.service.demo import demo_shapes

K = 20
CURVES = [{"source": [10, 2000], "target": [10, 2000]}, {"source": [500, 3500], "target": [500, 3500]}]
ZIPPED = {"target_textured.obj", "target_textured.mtl", "target_textured.png"}


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
    assert "0-based" in str(loaded["note"])


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
    _, session_id = api.demo_pair(tmp_path_factory.mktemp("shapes"), K)
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
    assert answer.headers["x-revision"] == str(served_map["revision"])
    assert f"_r{served_map['revision']}.mat" in answer.headers["content-disposition"]
    assert np.array_equal(loaded["C_source_to_target"], np.array(served_map["C_source_to_target"]))
    assert np.array_equal(loaded["C_target_to_source"], np.array(served_map["C_target_to_source"]))

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
    context.close()
    served_map = api.client.get(f"/sessions/{session_id}/map").json()
    assert np.array_equal(loaded["C_source_to_target"], np.array(served_map["C_source_to_target"]))
    assert name == f"maps_{session_id}_r{served_map['revision']}.mat"
    assert mesh.n_vertices == demo_shapes()[1].n_vertices
