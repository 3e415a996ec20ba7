"""The malformed-mesh corpus (tests/support/mesh_corpus.py) uploaded through the API of a real server: each file is
refused with the 4xx its manifest documents, in a body that matches ``ErrorBody``, and leaves the data directory as it
was, or is accepted with the documented vertex and face counts; the server answers ``/health`` after each."""

from __future__ import annotations

from pathlib import Path

import pytest
from support.mesh_corpus import MANIFEST, corpus_dir

from curvefm.service.errors import STATUS
from curvefm.service.models import ErrorBody

CORPUS = corpus_dir()
STATUS_OF_KIND = {cls.code: status for cls, status in STATUS.items()}


@pytest.fixture(scope="module")
def server(module_processes, tmp_path_factory):
    data = tmp_path_factory.mktemp("corpus") / "data"
    api = module_processes.api(data)
    api.data = data
    return api


def files_in(folder: Path) -> dict[str, int]:
    return {str(p.relative_to(folder)): p.stat().st_size for p in folder.rglob("*") if p.is_file()}


@pytest.mark.parametrize("name", sorted(MANIFEST))
def test_each_corpus_file_through_the_api(server, name):
    expected = MANIFEST[name]
    before = files_in(server.data)
    response = server.client.post("/shapes", files={"file": (name, (CORPUS / "meshes" / name).read_bytes())})
    assert server.client.get("/health").status_code == 200, f"the server is unwell after {name}"
    if expected["expect"] == "reject":
        assert response.status_code == STATUS_OF_KIND[expected["kind"]], response.text
        body = response.json()
        assert set(body) <= set(ErrorBody.model_fields) and ErrorBody.model_validate(body), body
        assert body["error"] == expected["kind"] and expected["message"] in body["detail"], body
        assert files_in(server.data) == before, f"refusing {name} changed the data directory"
    else:
        assert response.status_code in (200, 201), response.text
        shape = response.json()
        assert (shape["n_vertices"], shape["n_faces"]) == (expected["vertices"], expected["faces"])
        assert shape["has_uv"] == expected["uv"]
