"""An edit's answer carries the transferred function (``?carry=``), on a real server whose FAUST pair is drawn
coarse (``CURVEFM_DISPLAY_VERTICES=3000``): the carried rows are those ``GET /sessions/{id}/transfer`` gives for
the same revision, to within their 16-bit quantisation, at both resolutions and for every kind of edit."""

from __future__ import annotations

import numpy as np
import pytest
from support.display import display_server, mesh
from support.errors import expect as error_body

from curvefm.service.carried import CarriedFunction, decoded


@pytest.fixture(scope="module")
def server(module_processes, tmp_path_factory, shared_data):
    api = display_server(module_processes, tmp_path_factory.mktemp("carried"), shared_data)
    # the curve energy has no landmark prior landing later: a transfer read after the edit shows the same map
    created = api.client.post(
        "/sessions", json={"source": api.shapes[0], "target": api.shapes[1], "k": 30, "energy": "curves"}
    )
    api.plain = created.raise_for_status().json()["id"]
    return api


def transfer(server, session: str, **params) -> tuple[np.ndarray, int]:
    response = server.client.get(f"/sessions/{session}/transfer", params=params).raise_for_status()
    n, d = map(int, response.headers["X-Shape"].split(","))
    return np.frombuffer(response.content, "<f4").reshape(n, d), int(response.headers["X-Revision"])


def check_carried(server, answer: dict, function: str, resolution: str) -> None:
    carried = CarriedFunction.model_validate(answer["carried"])
    assert carried.function == function and carried.revision == answer["map"]["revision"]
    expected, revision = transfer(server, server.plain, function=function, resolution=resolution)
    assert revision == carried.revision and (carried.rows, carried.columns) == expected.shape
    assert expected.std() > 0  # a real texture, not a constant a wrong decoding would also match
    tolerance = np.asarray(carried.step) / 2 + 1e-6
    assert (np.abs(decoded(carried) - expected) <= tolerance).all()


def test_every_kind_of_edit_carries_the_transfer_of_its_revision(server):
    shown = len(mesh(server, server.shapes[1])[1]["vertex_ids"])
    path = f"/sessions/{server.plain}/curves"
    added = server.client.post(
        path, params={"carry": "uv", "resolution": "display"}, json={"source": [412, 5891], "target": [412, 5891]}
    )
    answer = added.raise_for_status().json()
    assert answer["carried"]["rows"] == shown < 6890
    check_carried(server, answer, "uv", "display")

    second = server.client.post(path, params={"carry": "xyz"}, json={"source": [3057, 6617], "target": [3057, 6617]})
    answer = second.raise_for_status().json()
    assert answer["carried"]["rows"] == 6890  # resolution=full by default
    check_carried(server, answer, "xyz", "full")

    curve = answer["curve"]["id"]
    replaced = server.client.put(
        f"{path}/{curve}", params={"carry": "uv"}, json={"source": [3057, 6000], "target": [3057, 6000]}
    )
    check_carried(server, replaced.raise_for_status().json(), "uv", "full")

    removed = server.client.delete(f"{path}/{curve}", params={"carry": "uv", "resolution": "display"})
    check_carried(server, removed.raise_for_status().json(), "uv", "display")


def test_an_edit_without_carry_answers_as_before(server):
    answer = server.client.post(f"/sessions/{server.session}/curves", json={"source": [19, 432], "target": [19, 432]})
    assert answer.raise_for_status().json()["carried"] is None


def test_the_combined_energy_says_when_its_prior_is_still_to_land(server):
    added = server.client.post(
        f"/sessions/{server.session}/curves",
        params={"carry": "uv"},
        json={"source": [100, 4000], "target": [100, 4000]},
    )
    carried = added.raise_for_status().json()["carried"]
    assert carried["revision"] == added.json()["map"]["revision"] and isinstance(carried["prior_pending"], bool)


@pytest.mark.parametrize(
    ("params", "named"), [({"carry": "indicator"}, "carry"), ({"carry": "uv", "resolution": "x"}, "resolution")]
)
def test_a_bad_carry_is_refused_and_nothing_is_stored(server, params, named):
    before = server.client.get(f"/sessions/{server.plain}").json()["revision"]
    spec = {"source": [1, 2000], "target": [1, 2000]}
    refused = server.client.post(f"/sessions/{server.plain}/curves", params=params, json=spec)
    error_body(refused, 422, "invalid", f"query.{named}")
    assert server.client.get(f"/sessions/{server.plain}").json()["revision"] == before
