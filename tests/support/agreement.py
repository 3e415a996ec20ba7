"""The agreement and check-member tests' FAUST collection, and what they compute from a session as the service
does: a click beside a vertex, and a session's live map from its served functional maps."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from curvefm.geometry import Mesh, farthest_point_sampling, load_mesh
from curvefm.pointwise import pointwise_from_both
from curvefm.store import Store

K = 40
"""The basis size of the tests' collections."""


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


@dataclass(frozen=True)
class FaustCollection:
    base: str
    """The collection's URL path."""
    template: str
    members: list[str]
    """The members' shape ids (m1, m2, ...)."""
    template_mesh: Mesh
    member_meshes: list[Mesh]
    ends: list[int]
    """The template curves' ends (t1 from ends[0] to ends[1], ...)."""
    curves: list[dict]
    clients: dict
    """The annotators' clients, by name."""


def faust_collection(api, shared_data, names: tuple[str, ...], annotators: tuple[str, ...]) -> FaustCollection:
    """The owner's collection on FAUST registrations ``tr_reg_<name>`` (the first the template, the others its
    members), its 6 template curves between 12 farthest points, once its bases are ready, ``annotators`` holding
    the annotator role."""
    paths = [shared_data / "faust" / f"tr_reg_{name}.off" for name in names]
    template, *members = (api.upload(path) for path in paths)
    template_mesh, *member_meshes = (load_mesh(path) for path in paths)
    ends = farthest_point_sampling(template_mesh, 12).tolist()
    curves = [{"waypoints": pair} for pair in zip(ends[0::2], ends[1::2], strict=True)]
    body = {"template": template, "curves": curves, "members": members, "k": K}
    view = api.client.post("/collections", json=body).raise_for_status().json()
    base = f"/collections/{view['collection']['id']}"
    for job in [m["basis_job"] for m in view["members"]]:
        api.wait_job(job)
    clients = {name: api.client_for(name) for name in annotators}
    for name in annotators:
        api.client.put(f"{base}/roles/{name}", json={"role": "annotator"}).raise_for_status()
    return FaustCollection(base, template, members, template_mesh, member_meshes, ends, curves, clients)
