"""Display copies over HTTP, shared by the service's and the UI's display tests: a server whose threshold is set
low (``CURVEFM_DISPLAY_VERTICES=3000``) so that FAUST's 6,890-vertex scans are drawn coarse, with a session of two
curves; and the decoder of the binary mesh payload (``GET /shapes/{id}/mesh``, ``POST /shapes/{id}/points``)."""

from __future__ import annotations

import json
import struct

import numpy as np

THRESHOLD = 3000
K = 30
CURVES = ({"source": [412, 5891], "target": [412, 5891]}, {"source": [3057, 6617], "target": [3057, 6617]})


def display_server(processes, folder, shared_data):
    """An API whose FAUST pair (tr_reg_000 -> tr_reg_011) is drawn coarse, with a session of two curves."""
    api = processes.api(folder / "data", env={"CURVEFM_DISPLAY_VERTICES": str(THRESHOLD)})
    api.shapes = [api.upload(shared_data / "faust" / f"tr_reg_{n}.off") for n in ("000", "011")]
    for shape_id in api.shapes:
        job = api.client.post(f"/shapes/{shape_id}/bases", json={"k": K}).raise_for_status().json()
        assert api.wait_job(job["id"])["state"] == "finished"
    created = api.client.post("/sessions", json={"source": api.shapes[0], "target": api.shapes[1], "k": K})
    api.session = created.raise_for_status().json()["id"]
    for curve in CURVES:
        api.client.post(f"/sessions/{api.session}/curves", json=curve).raise_for_status()
    return api


def decode(payload: bytes) -> tuple[dict, dict[str, np.ndarray]]:
    """The header and arrays of the binary layout of GET /shapes/{id}/mesh."""
    (length,) = struct.unpack("<I", payload[:4])
    header = json.loads(payload[4 : 4 + length])
    arrays = {}
    for name, layout in header["arrays"].items():
        start, count = 4 + length + layout["offset"], int(np.prod(layout["shape"]))
        arrays[name] = np.frombuffer(payload, layout["dtype"], count, start).reshape(layout["shape"])
    return header, arrays


def mesh(server, shape_id: str, **params) -> tuple[dict, dict[str, np.ndarray]]:
    return decode(server.client.get(f"/shapes/{shape_id}/mesh", params=params).raise_for_status().content)
