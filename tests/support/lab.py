"""A lab for the access tests: one real API process, callers of every kind, small shapes with bases."""

from __future__ import annotations

import itertools
import time

import httpx

from curvefm.access import TOKEN_PREFIX
from support.processes import Api, bearer
from support.shapes import ellipsoid, off_bytes

K = 10
CURVE = {"source": [0, 60], "target": [0, 60]}


class Lab:
    """``owner`` is the API fixture's user; ``other`` a second user; ``admin`` an admin; ``anonymous`` sends no
    credentials and ``wrong`` a token no user has. ``shapes``: two small ellipsoids (130 vertices, same ids) of
    the owner with bases of ``K`` functions."""

    def __init__(self, api: Api):
        self.api = api
        self.owner = api.client
        self.other = api.client_for("oscar")
        self.admin = api.client_for("ada", admin=True)
        self.anonymous = httpx.Client(base_url=api.url, timeout=120)
        self.wrong = httpx.Client(base_url=api.url, timeout=120, headers=bearer(TOKEN_PREFIX + "x" * 43))
        self._scales = itertools.count(1)
        self.meshes = {}  # shape id -> the mesh uploaded
        self.shapes = [self.upload(self.owner, ellipsoid(8, 16)), self.upload(self.owner, ellipsoid(8, 16, (1, 1, 1)))]
        for shape_id in self.shapes:
            self.basis(self.owner, shape_id)

    def caller(self, name: str) -> httpx.Client:
        return getattr(self, name)

    def upload(self, client: httpx.Client, mesh) -> str:
        response = client.post("/shapes", files={"file": ("shape.off", off_bytes(mesh))})
        assert response.status_code in (200, 201), response.text
        self.meshes[response.json()["id"]] = mesh
        return response.json()["id"]

    def new_shape(self, client: httpx.Client | None = None) -> str:
        """A shape no one uploaded before (a differently scaled ellipsoid), uploaded by ``client`` (the owner)."""
        return self.upload(client or self.owner, ellipsoid(8, 16, scale=1 + next(self._scales) / 100))

    def basis(self, client: httpx.Client, shape_id: str) -> dict:
        job = client.post(f"/shapes/{shape_id}/bases", json={"k": K}).raise_for_status().json()
        return self.wait_job(client, job["id"])

    def new_session(self, client: httpx.Client | None = None, **fields) -> str:
        body = {"source": self.shapes[0], "target": self.shapes[1], "k": K, **fields}
        return (client or self.owner).post("/sessions", json=body).raise_for_status().json()["id"]

    def add_curve(self, client: httpx.Client, session_id: str) -> str:
        edit = client.post(f"/sessions/{session_id}/curves", json=CURVE).raise_for_status().json()
        return edit["curve"]["id"]

    def refined(self, client: httpx.Client, session_id: str) -> dict:
        """A finished nearest-neighbour refinement of the session, started by ``client``."""
        job = client.post(f"/sessions/{session_id}/refine", json={"converter": "nearest-neighbor"})
        return self.wait_job(client, job.raise_for_status().json()["id"])

    def new_collection(self, client: httpx.Client, session_id: str) -> str:
        """A private collection on the session's source, its curves the template curves, its target member m1."""
        body = {"template": self.shapes[0], "from_session": session_id}
        return client.post("/collections", json=body).raise_for_status().json()["collection"]["id"]

    def finished_run(self, client: httpx.Client, collection_id: str, timeout: float = 120) -> str:
        """The id of a nearest-neighbour run of every member of the collection, once it has finished."""
        run = client.post(f"/collections/{collection_id}/runs", json={"converter": "nearest-neighbor"})
        run_id = run.raise_for_status().json()["id"]
        deadline = time.monotonic() + timeout
        while (status := client.get(f"/collections/{collection_id}/runs/{run_id}").json())["state"] != "finished":
            assert status["state"] not in ("failed", "canceled") and time.monotonic() < deadline, status
            time.sleep(0.1)
        return run_id

    @staticmethod
    def wait_job(client: httpx.Client, job_id: str, timeout: float = 120) -> dict:
        deadline = time.monotonic() + timeout
        while (info := client.get(f"/jobs/{job_id}").raise_for_status().json())["state"] not in (
            "finished",
            "failed",
            "canceled",
        ):
            assert time.monotonic() < deadline, info
            time.sleep(0.05)
        assert info["state"] == "finished", info
        return info
