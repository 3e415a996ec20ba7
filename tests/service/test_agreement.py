"""Double annotation on FAUST over HTTP against a real API process: two annotators answer the same member's
template curves from the ground truth (FAUST registrations share vertex ids, the true map is the identity), one at
the true endpoints and one a few vertices beside them; the agreement the service reports is checked against the
same measures computed here from the sessions' served maps, their stored bases and the clicked endpoints."""

from __future__ import annotations

import io
import json

import numpy as np

from curvefm.geometry import farthest_point_sampling, load_mesh, pair_geodesic_distances
from curvefm.pointwise import pointwise_from_both
from curvefm.store import Store

K = 40
POINTS = 300


def beside(mesh, vertex: int, rank: int = 12) -> int:
    """The ``rank``-th nearest vertex to ``vertex`` (Euclidean): a click a little off the true endpoint."""
    distances = np.linalg.norm(mesh.vertices - mesh.vertices[vertex], axis=1)
    return int(np.argsort(distances)[rank])


def served_map(client, store: Store, session_id: str, template: str, member: str, rows: np.ndarray) -> np.ndarray:
    """The session's live map at the template vertices ``rows``: member vertices, from its served functional maps
    and the stored bases."""
    maps = client.get(f"/sessions/{session_id}/map").raise_for_status().json()
    C_MN, C_NM = np.array(maps["C_source_to_target"]), np.array(maps["C_target_to_source"])
    basis_M, basis_N = store.find_basis(template, K), store.find_basis(member, K)
    return pointwise_from_both(C_NM, C_MN, basis_N, basis_M, rows=rows)


def test_double_annotation_agreement_against_a_hand_computation(processes, tmp_path, shared_data):
    api = processes.api(tmp_path / "data", env={"CURVEFM_AGREEMENT_POINTS": str(POINTS)})
    owner = api.client
    paths = [shared_data / "faust" / f"tr_reg_{n}.off" for n in ("000", "001")]
    template, member = (api.upload(path) for path in paths)
    template_mesh, member_mesh = (load_mesh(path) for path in paths)
    ends = farthest_point_sampling(template_mesh, 12).tolist()
    curves = [{"waypoints": pair} for pair in zip(ends[0::2], ends[1::2], strict=True)]
    body = {"template": template, "curves": curves, "members": [member], "k": K}
    view = owner.post("/collections", json=body).raise_for_status().json()
    base = f"/collections/{view['collection']['id']}"
    for job in [m["basis_job"] for m in view["members"]]:
        api.wait_job(job)
    ann, abe = api.client_for("ann"), api.client_for("abe")
    for name in ("ann", "abe"):
        owner.put(f"{base}/roles/{name}", json={"role": "annotator"}).raise_for_status()
    owner.put(f"{base}/members/m1/assignee", json={"user": "ann"}).raise_for_status()
    further = owner.post(f"{base}/members/m1/annotations", json={"user": "abe"})
    assert further.status_code == 201, further.text
    assert owner.post(f"{base}/members/m1/annotations", json={"user": "abe"}).status_code == 409
    assert owner.post(f"{base}/members/m1/annotations", json={"user": "ann"}).status_code == 409  # its assignee
    assert ann.post(f"{base}/members/m1/annotations", json={"user": "ann"}).status_code == 403

    clicked = {"ann": [], "abe": []}
    for number, curve in enumerate(curves, 1):
        start, end = curve["waypoints"]
        answer = {"template_curve": f"t{number}", "target": [start, end]}
        ann.post(f"{base}/members/m1/curves", json=answer).raise_for_status()
        moved = {"template_curve": f"t{number}", "target": [beside(member_mesh, start), beside(member_mesh, end)]}
        abe.post(f"{base}/members/m1/curves", params={"annotator": "abe"}, json=moved).raise_for_status()
        clicked["ann"].append(answer["target"])
        clicked["abe"].append(moved["target"])
    assert abe.post(f"{base}/members/m1/curves", json=answer).status_code == 403  # m1's own session is ann's
    assert ann.post(f"{base}/members/m1/curves", params={"annotator": "abe"}, json=answer).status_code == 403
    assert ann.post(f"{base}/members/m1/curves", params={"annotator": "zed"}, json=answer).status_code == 404

    annotations = abe.get(f"{base}/annotations").raise_for_status().json()
    assert [(a["member"], a["annotator"], a["further"]) for a in annotations] == [
        ("m1", "ann", False),
        ("m1", "abe", True),
    ]
    report = abe.get(f"{base}/agreement").raise_for_status().json()
    assert report["points"] == POINTS and [m["member"] for m in report["members"]] == ["m1"]
    (pair,) = report["members"][0]["pairs"]
    assert (pair["a"], pair["b"]) == ("ann", "abe")

    scale = np.sqrt(member_mesh.area)
    a_ends, b_ends = (member_mesh.internal_ids(np.array(clicked[name]).reshape(-1)) for name in ("ann", "abe"))
    by_hand = (pair_geodesic_distances(member_mesh, a_ends, b_ends) / scale).reshape(-1, 2)
    served = np.array([[c["start"], c["end"]] for c in pair["curves"]])
    assert [c["template_curve"] for c in pair["curves"]] == [f"t{n}" for n in range(1, 7)]
    np.testing.assert_allclose(served, by_hand, rtol=1e-9)
    assert (by_hand > 0).all()
    assert np.isclose(pair["endpoint_distance"], by_hand.mean())

    store = Store(api.data_dir)
    rows = farthest_point_sampling(template_mesh, POINTS)
    maps = [served_map(abe, store, pair[f"session_{s}"], template, member, rows) for s in ("a", "b")]
    map_by_hand = pair_geodesic_distances(member_mesh, maps[0], maps[1]).mean() / scale
    assert np.isclose(pair["map_distance"], map_by_hand, rtol=1e-6), (pair["map_distance"], map_by_hand)
    assert 0 < map_by_hand < 0.1  # both near the identity, not the same map
    assert np.isclose(report["map_distance"], map_by_hand) and report["flagged"] == []
    figures = {a["annotator"]: a for a in report["annotators"]}
    assert list(figures) == ["abe", "ann"] and all(a["members"] == 1 for a in figures.values())
    for figure in figures.values():
        assert np.isclose(figure["map_distance"], map_by_hand)
        assert np.isclose(figure["endpoint_distance"], by_hand.mean())

    assert api.client_for("oscar").get(f"{base}/agreement").status_code == 404

    run = owner.post(f"{base}/runs", json={"converter": "nearest-neighbor"}).raise_for_status().json()
    assert [api.wait_job(m["job"])["state"] for m in run["members"]] == ["finished"]
    archive = np.load(io.BytesIO(owner.get(f"{base}/runs/{run['id']}/archive.npz").raise_for_status().content))
    assert json.loads(str(archive["summary.json"]))["agreement"] == report  # the archive's summary carries it
