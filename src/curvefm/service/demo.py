"""The demo: two shapes generated in code, their bases computed through the job queue, a session with curves.

The source is a four-legged "animal" (a sphere pushed out into legs, a head and a tail); the target is a
strongly non-isometric deformation of it with the same connectivity (fatter belly, longer legs, bigger head,
raised tail), so vertex i corresponds to vertex i. The session is stored under the id ``demo``, owned by the
local admin and shared editable with every user.
"""

from __future__ import annotations

import logging
import threading

import numpy as np

from curvefm import registry
from curvefm.errors import InternalError
from curvefm.fmap import DEFAULT_K
from curvefm.geometry import Mesh, build_mesh
from curvefm.service.auth import LOCAL_ADMIN
from curvefm.service.deps import Services, stored_mesh_bytes, submit_basis
from curvefm.session import CurveSpec, SessionCreate

log = logging.getLogger("curvefm.demo")

DEMO_SESSION = "demo"
SUBDIVISIONS = 5  # 4098 vertices
LEGS = [(0.55, 0.45, -1.0), (0.55, -0.45, -1.0), (-0.55, 0.45, -1.0), (-0.55, -0.45, -1.0)]
HEAD, TAIL = (1.0, 0.0, 0.35), (-1.0, 0.0, 0.25)
# (direction, height, width): radial bumps on the unit sphere before stretching it into a body
BUMPS = [(leg, 0.9, 0.035) for leg in LEGS] + [(HEAD, 0.55, 0.08), (TAIL, 1.1, 0.012)]


def octasphere(subdivisions: int) -> tuple[np.ndarray, np.ndarray]:
    """Unit sphere from a subdivided octahedron: 4 * 4**subdivisions + 2 vertices, faces outward."""
    vertices = np.vstack([np.eye(3), -np.eye(3)])  # +x +y +z -x -y -z
    faces = np.array([[0, 1, 2], [1, 3, 2], [3, 4, 2], [4, 0, 2], [1, 0, 5], [3, 1, 5], [4, 3, 5], [0, 4, 5]])
    for _ in range(subdivisions):
        vertices, faces = _split_edges(vertices, faces)
    return vertices / np.linalg.norm(vertices, axis=1, keepdims=True), faces


def _split_edges(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    edges = np.sort(faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    unique, inverse = np.unique(edges, axis=0, return_inverse=True)
    middle = len(vertices) + inverse.reshape(-1, 3)  # new vertex on edges (0,1), (1,2), (2,0) of each face
    a, b, c = faces.T
    ab, bc, ca = middle.T
    new_faces = np.concatenate([np.c_[a, ab, ca], np.c_[ab, b, bc], np.c_[ca, bc, c], np.c_[ab, bc, ca]])
    return np.vstack([vertices, vertices[unique].mean(axis=1)]), new_faces


def demo_shapes() -> tuple[Mesh, Mesh]:
    sphere, faces = octasphere(SUBDIVISIONS)
    radius = np.ones(len(sphere))
    for direction, height, width in BUMPS:
        d = np.asarray(direction) / np.linalg.norm(direction)
        radius += height * np.exp(-(1 - sphere @ d) / width)
    source = sphere * radius[:, None] * np.array([1.8, 0.8, 0.7])
    return build_mesh(source, faces, name="demo-animal"), build_mesh(
        _deform(source), faces, name="demo-animal-deformed"
    )


def _deform(points: np.ndarray) -> np.ndarray:
    x, y, z = points.T
    belly = 1 + 0.6 * np.exp(-((x / 0.9) ** 2)) * (z > -0.9)
    legs = np.where(z < -0.6, 1.6, 1.0)
    head = np.where(x > 1.6, 1 + 0.5 * np.tanh(3 * (x - 1.6)), 1.0)
    tail_lift = np.where(x < -1.5, 0.8 * (x + 1.5) ** 2, 0.0)
    return np.c_[x * (1 + 0.25 * np.tanh(x)), y * belly * head, z * legs * head + tail_lift]


def demo_curves(mesh: Mesh) -> list[CurveSpec]:
    """Head to tail, from the front to the back leg of one side, and from the head down that front leg (same ids
    on both shapes): all on the side the UI shows by default (+y), where curves across a pair of legs ran under
    the belly, out of view."""
    tip = {
        name: int(np.argmax(mesh.vertices @ (np.asarray(d) / np.linalg.norm(d))))
        for name, d in (("head", HEAD), ("tail", TAIL), *(zip(("fl", "fr", "bl", "br"), LEGS, strict=True)))
    }
    pairs = [("head", "tail"), ("fl", "bl"), ("head", "fl")]
    return [CurveSpec(source=[tip[a], tip[b]], target=[tip[a], tip[b]]) for a, b in pairs]


def start_demo(services: Services) -> threading.Event:
    """Prepare the demo in a background thread (the API answers meanwhile); set the event to give up."""
    stop = threading.Event()
    threading.Thread(target=_run_logged, args=(services, stop), name="curvefm-demo", daemon=True).start()
    return stop


def _run_logged(services: Services, stop: threading.Event) -> None:
    try:
        prepare_demo(services, stop)
    except Exception:
        log.exception("the demo could not be prepared")


def prepare_demo(services: Services, stop: threading.Event, k: int = DEFAULT_K) -> None:
    if services.records.exists(DEMO_SESSION):
        log.info("demo session '%s' is ready", DEMO_SESSION)
        return
    meshes = demo_shapes()
    ids = [services.store.put_mesh(mesh) for mesh in meshes]
    admin = services.users.get(LOCAL_ADMIN)  # the local admin owns the demo; without one (other users), nobody
    owner = admin.name if admin else ""
    for mesh_id in ids:
        services.shapes.add(mesh_id, stored_mesh_bytes(services.store, mesh_id) or 0, admin.id if admin else None)
    params = registry.get("basis", "laplace-beltrami").parse_params({}).model_dump()
    jobs = [submit_basis(services, mesh_id, k, "laplace-beltrami", params, owner) for mesh_id in ids]
    for mesh, job in zip(meshes, jobs, strict=True):
        if not _wait(services, job.id, f"basis of {mesh.name} ({mesh.n_vertices} vertices, k={k})", stop):
            return
    request = SessionCreate(source=ids[0], target=ids[1], k=k, name="demo", sharing="edit")
    services.sessions.create(request, DEMO_SESSION, owner=owner)
    for spec in demo_curves(meshes[0]):
        services.sessions.add_curve(DEMO_SESSION, spec)
    log.info(
        "demo session '%s' is ready: open /?session=%s (log in first with the URL printed at the start)",
        DEMO_SESSION,
        DEMO_SESSION,
    )


def _wait(services: Services, job_id: str, what: str, stop: threading.Event) -> bool:
    """Log the job's progress until it finishes (True) or the service shuts down (False)."""
    shown = None
    while not stop.is_set():
        info = services.queue.get(job_id)
        if (info.state, info.message) != shown:
            log.info("demo: %s: %s %3.0f%% %s", what, info.state, 100 * info.progress, info.message)
            shown = (info.state, info.message)
        if info.state == "finished":
            return True
        if info.state in ("failed", "canceled"):
            raise InternalError(f"demo: {what} {info.state}: {info.error.message if info.error else info.message}")
        stop.wait(0.5)
    return False
