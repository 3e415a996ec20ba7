"""Double annotation on FAUST over HTTP against a real API process: two annotators answer the same member's
template curves from the ground truth (FAUST registrations share vertex ids, the true map is the identity), one at
the true endpoints and one a few vertices beside them; the agreement the service reports is checked against the
same measures computed here from the sessions' served maps, their stored bases and the clicked endpoints."""

from __future__ import annotations

import io
import json

import numpy as np
from support.agreement import beside, faust_collection, served_map

from curvefm.geometry import farthest_point_sampling, pair_geodesic_distances
from curvefm.store import Store

POINTS = 300


def test_double_annotation_agreement_against_a_hand_computation(processes, tmp_path, shared_data):
    api = processes.api(tmp_path / "data", env={"CURVEFM_AGREEMENT_POINTS": str(POINTS)})
    owner = api.client
    faust = faust_collection(api, shared_data, ("000", "001"), ("ann", "abe"))
    base, template, (member,), member_mesh = faust.base, faust.template, faust.members, faust.member_meshes[0]
    curves, template_mesh = faust.curves, faust.template_mesh
    ann, abe = faust.clients["ann"], faust.clients["abe"]
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
