"""The access matrix, over HTTP against a real server process.

Every route of the served OpenAPI schema is asked by five callers: anonymous, a wrong token, another user, the
owner of what the request names, and an admin. Each route has a rule below saying what each caller gets; a route
without a rule (or a rule without a route) fails the test, so no route ships before someone decided who may use
it. Requests that destroy what they name (a session, a shape, a curve) get a fresh one for every caller.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass, field

import pytest
from fastapi.routing import APIRoute
from starlette.routing import Mount
from support.lab import CURVE, K, Lab
from support.morphometrics import mrk_file
from support.processes import TEST_USER
from support.shapes import ellipsoid, off_bytes

from curvefm.service.app import create_app
from curvefm.service.auth import bearer_user, current_user
from curvefm.service.models import ErrorBody
from curvefm.service.settings import Settings
from curvefm.service.ui import VENDOR_URLS

CALLERS = ("anonymous", "wrong", "other", "owner", "admin")
WEBHOOK_URL = "https://hooks.example/curvefm"
OK = "2xx"


@dataclass(frozen=True)
class Call:
    path: dict[str, str] = field(default_factory=dict)
    json: object = None
    params: dict | None = None
    files: dict | None = None


@dataclass(frozen=True)
class Rule:
    """``build(world)`` makes the request; ``other``, ``owner`` and ``admin`` (by default what the owner gets)
    are the statuses expected, ``OK`` for any 2xx. Callers without valid credentials get 401 unless the route is
    ``public`` (then what ``other`` gets). ``new_token``: a success answers the caller's new token, which the
    caller's client sends from then on."""

    build: Callable[[World], Call]
    other: int | str = OK
    owner: int | str = OK
    admin: int | str | None = None
    public: bool = False
    new_token: bool = False

    def expected(self, caller: str) -> int | str:
        if caller in ("anonymous", "wrong"):
            return self.other if self.public else 401
        if caller == "admin" and self.admin is not None:
            return self.admin
        return self.other if caller == "other" else self.owner


@dataclass
class World:
    """What the requests name: the owner's private session with a curve and a finished refinement job, and the
    owner's private collection made from that session (member m1, template curve t1) with a finished run."""

    lab: Lab
    session: str
    curve: str
    job: str
    file: str
    collection: str = ""
    run: str = ""
    uploads: int = 0

    def fresh_shape(self) -> str:
        return self.lab.new_shape()

    def fresh_session(self) -> str:
        return self.lab.new_session()

    def fresh_curve(self) -> str:
        return self.lab.add_curve(self.lab.owner, self.session)

    def fresh_collection(self) -> str:
        return self.lab.new_collection(self.lab.owner, self.session)

    grantee = "grace"
    """A user who is granted roles in the owner's collection (never the ``other`` caller)."""

    def granted(self) -> str:
        """:attr:`grantee`, holding a role in the owner's collection now."""
        grant = self.lab.owner.put(f"/collections/{self.collection}/roles/{self.grantee}", json={"role": "viewer"})
        grant.raise_for_status()
        return self.grantee

    def fresh_mesh_file(self) -> tuple[str, bytes]:
        """A mesh file no collection has as a member yet (a collection refuses a shape twice)."""
        self.uploads += 1
        return "e.off", off_bytes(ellipsoid(6, 12, scale=2 + self.uploads / 100))

    def fresh_webhook(self) -> str:
        """A new webhook of the owner's collection."""
        body = {"url": WEBHOOK_URL, "events": ["run.ended"]}
        return (
            self.lab.owner.post(f"/collections/{self.collection}/webhooks", json=body).raise_for_status().json()["id"]
        )

    def truth_file(self) -> dict:
        """The identity ground truth of member m1 (the template and its shape are ellipsoids alike)."""
        vertices = self.lab.meshes[self.lab.shapes[0]].n_file_vertices
        return {"file": ("truth.txt", "".join(f"{i}\n" for i in range(vertices)).encode())}

    def with_truth(self) -> str:
        """Member m1 of the owner's collection, a check member now."""
        truth = f"/collections/{self.collection}/members/m1/truth"
        self.lab.owner.put(truth, files=self.truth_file()).raise_for_status()
        return "m1"

    def submitted_collection(self) -> str:
        """A fresh collection of the owner whose member m1 (with the session's curve) is submitted for review."""
        collection_id = self.fresh_collection()
        self.lab.owner.post(f"/collections/{collection_id}/members/m1/submit").raise_for_status()
        return collection_id

    def fresh_comment(self) -> str:
        """A new review comment of the owner on member m1 of the owner's collection."""
        body = {"text": "look here", "side": "target", "vertex": 0}
        comments = f"/collections/{self.collection}/members/m1/comments"
        return self.lab.owner.post(comments, json=body).raise_for_status().json()["id"]

    def fresh_member(self) -> str:
        """A new member of the owner's collection (on a new shape)."""
        members = f"/collections/{self.collection}/members"
        view = self.lab.owner.post(members, json={"shapes": [self.fresh_shape()]}).raise_for_status().json()
        return view["members"][-1]["id"]


def session(world: World, **more) -> dict:
    return {"session_id": world.session, **more}


def collection(world: World, **more) -> dict:
    return {"collection_id": world.collection, **more}


def run(world: World, **more) -> dict:
    return collection(world, run_id=world.run, **more)


def markups(world: World) -> dict:
    """Slicer markups of the lab's CURVE on each of its two shapes."""
    files = {}
    for side, shape_id in zip(("source", "target"), world.lab.shapes, strict=True):
        mesh = world.lab.meshes[shape_id]
        points = mesh.vertices[mesh.internal_ids(CURVE[side])]
        files[side] = (f"{side}.mrk.json", mrk_file([("Curve", "c", ["a", "b"], points)]))
    return files


RULES: dict[tuple[str, str], Rule] = {
    ("get", "/health"): Rule(lambda w: Call(), public=True),
    ("post", "/auth/login"): Rule(lambda w: Call()),
    ("post", "/auth/logout"): Rule(lambda w: Call()),
    ("get", "/auth/me"): Rule(lambda w: Call()),
    ("post", "/auth/token"): Rule(lambda w: Call(), new_token=True),
    ("get", "/auth/methods"): Rule(lambda w: Call(), public=True),
    # single sign-on is not configured here (tests/access/test_single_sign_on.py signs in where it is)
    ("get", "/auth/oidc/login"): Rule(lambda w: Call(), other=404, owner=404, public=True),
    ("get", "/auth/oidc/callback"): Rule(
        lambda w: Call(params={"state": "s", "code": "c"}), other=404, owner=404, public=True
    ),
    ("get", "/plugins"): Rule(lambda w: Call()),
    ("get", "/audit"): Rule(lambda w: Call(params={"limit": 5}), other=403, owner=403, admin=OK),
    ("get", "/shapes"): Rule(lambda w: Call()),
    ("post", "/shapes"): Rule(lambda w: Call(files={"file": ("e.off", off_bytes(ellipsoid(6, 12)))})),
    ("get", "/shapes/{shape_id}"): Rule(lambda w: Call({"shape_id": w.lab.shapes[0]})),
    ("get", "/shapes/{shape_id}/mesh"): Rule(lambda w: Call({"shape_id": w.lab.shapes[0]})),
    ("post", "/shapes/{shape_id}/points"): Rule(lambda w: Call({"shape_id": w.lab.shapes[0]}, json={"vertices": [0]})),
    ("post", "/shapes/{shape_id}/bases"): Rule(lambda w: Call({"shape_id": w.lab.shapes[0]}, json={"k": K})),
    ("delete", "/shapes/{shape_id}"): Rule(lambda w: Call({"shape_id": w.fresh_shape()}), other=403),
    ("delete", "/shapes/{shape_id}/bases"): Rule(lambda w: Call({"shape_id": w.fresh_shape()}), other=403),
    ("get", "/sessions"): Rule(lambda w: Call()),
    ("post", "/sessions"): Rule(lambda w: Call(json={"source": w.lab.shapes[0], "target": w.lab.shapes[1], "k": K})),
    ("get", "/sessions/{session_id}"): Rule(lambda w: Call(session(w)), other=404),
    ("patch", "/sessions/{session_id}"): Rule(lambda w: Call(session(w), json={"sharing": "private"}), other=404),
    ("delete", "/sessions/{session_id}"): Rule(lambda w: Call({"session_id": w.fresh_session()}), other=404),
    ("post", "/sessions/{session_id}/curves"): Rule(lambda w: Call(session(w), json=CURVE), other=404),
    ("put", "/sessions/{session_id}/curves/{curve_id}"): Rule(
        lambda w: Call(session(w, curve_id=w.curve), json=CURVE), other=404
    ),
    ("delete", "/sessions/{session_id}/curves/{curve_id}"): Rule(
        lambda w: Call(session(w, curve_id=w.fresh_curve())), other=404
    ),
    ("get", "/sessions/{session_id}/map"): Rule(lambda w: Call(session(w)), other=404),
    ("get", "/sessions/{session_id}/solve"): Rule(lambda w: Call(session(w)), other=404),
    ("get", "/sessions/{session_id}/transfer"): Rule(lambda w: Call(session(w), params={"function": "xyz"}), other=404),
    ("get", "/sessions/{session_id}/quality"): Rule(lambda w: Call(session(w)), other=404),
    ("get", "/sessions/{session_id}/suggestion"): Rule(lambda w: Call(session(w)), other=404),
    ("get", "/sessions/{session_id}/refinements"): Rule(lambda w: Call(session(w)), other=404),
    ("get", "/sessions/{session_id}/events"): Rule(lambda w: Call(session(w)), other=404),
    ("get", "/sessions/{session_id}/exports/{export}"): Rule(
        lambda w: Call(session(w, export="target_textured.zip")), other=404
    ),
    ("post", "/sessions/{session_id}/markups"): Rule(lambda w: Call(session(w), files=markups(w)), other=404),
    ("post", "/sessions/{session_id}/refine"): Rule(
        lambda w: Call(session(w), json={"converter": "nearest-neighbor"}), other=404
    ),
    ("get", "/jobs/{job_id}"): Rule(lambda w: Call({"job_id": w.job}), other=404),
    # the job has finished: whoever may cancel or retry it is told there is nothing to cancel or retry
    ("delete", "/jobs/{job_id}"): Rule(lambda w: Call({"job_id": w.job}), other=404, owner=409),
    ("post", "/jobs/{job_id}/retry"): Rule(lambda w: Call({"job_id": w.job}), other=404, owner=409),
    ("get", "/jobs/{job_id}/files/{name}"): Rule(lambda w: Call({"job_id": w.job, "name": w.file}), other=404),
    ("get", "/collections"): Rule(lambda w: Call()),
    ("post", "/collections"): Rule(
        lambda w: Call(json={"template": w.lab.shapes[0], "curves": [{"waypoints": CURVE["source"]}], "k": K})
    ),
    ("get", "/collections/{collection_id}"): Rule(lambda w: Call(collection(w)), other=404),
    ("patch", "/collections/{collection_id}"): Rule(
        lambda w: Call(collection(w), json={"sharing": "private"}), other=404
    ),
    ("delete", "/collections/{collection_id}"): Rule(
        lambda w: Call({"collection_id": w.fresh_collection()}), other=404
    ),
    ("post", "/collections/{collection_id}/members"): Rule(
        lambda w: Call(collection(w), json={"shapes": [w.fresh_shape()]}), other=404
    ),
    ("delete", "/collections/{collection_id}/members/{member_id}"): Rule(
        lambda w: Call(collection(w, member_id=w.fresh_member())), other=404
    ),
    ("post", "/collections/{collection_id}/members/upload"): Rule(
        lambda w: Call(collection(w), files={"files": w.fresh_mesh_file()}), other=404
    ),
    ("post", "/collections/{collection_id}/members/{member_id}/curves"): Rule(
        lambda w: Call(collection(w, member_id="m1"), json={"template_curve": "t1", "target": CURVE["target"]}),
        other=404,
    ),
    ("get", "/collections/{collection_id}/roles"): Rule(lambda w: Call(collection(w)), other=404),
    ("put", "/collections/{collection_id}/roles/{user_name}"): Rule(
        lambda w: Call(collection(w, user_name=w.grantee), json={"role": "viewer"}), other=404
    ),
    ("delete", "/collections/{collection_id}/roles/{user_name}"): Rule(
        lambda w: Call(collection(w, user_name=w.granted())), other=404
    ),
    ("put", "/collections/{collection_id}/members/{member_id}/assignee"): Rule(
        lambda w: Call(collection(w, member_id="m1"), json={"user": None}), other=404
    ),
    ("post", "/collections/{collection_id}/assign"): Rule(
        lambda w: Call(collection(w), json={"annotators": [TEST_USER], "members": ["m1"]}), other=404
    ),
    ("get", "/collections/{collection_id}/assignments"): Rule(lambda w: Call(collection(w)), other=404),
    ("get", "/me/work"): Rule(lambda w: Call()),
    ("get", "/collections/{collection_id}/exports/{export}"): Rule(
        lambda w: Call(collection(w, export="landmarks.tps"), params={"complete_only": True}), other=404
    ),
    ("post", "/collections/{collection_id}/webhooks"): Rule(
        lambda w: Call(collection(w), json={"url": WEBHOOK_URL, "events": ["run.ended"]}), other=404
    ),
    ("get", "/collections/{collection_id}/webhooks"): Rule(lambda w: Call(collection(w)), other=404),
    ("delete", "/collections/{collection_id}/webhooks/{webhook_id}"): Rule(
        lambda w: Call(collection(w, webhook_id=w.fresh_webhook())), other=404
    ),
    ("get", "/collections/{collection_id}/webhooks/{webhook_id}/deliveries"): Rule(
        lambda w: Call(collection(w, webhook_id=w.fresh_webhook())), other=404
    ),
    ("post", "/collections/{collection_id}/members/{member_id}/submit"): Rule(
        lambda w: Call({"collection_id": w.fresh_collection(), "member_id": "m1"}), other=404
    ),
    ("post", "/collections/{collection_id}/members/{member_id}/review"): Rule(
        lambda w: Call({"collection_id": w.submitted_collection(), "member_id": "m1"}, json={"decision": "accept"}),
        other=404,
    ),
    ("get", "/collections/{collection_id}/reviews"): Rule(lambda w: Call(collection(w)), other=404),
    ("get", "/collections/{collection_id}/members/{member_id}/comments"): Rule(
        lambda w: Call(collection(w, member_id="m1")), other=404
    ),
    ("post", "/collections/{collection_id}/members/{member_id}/comments"): Rule(
        lambda w: Call(collection(w, member_id="m1"), json={"text": "here", "side": "source", "vertex": 0}),
        other=404,
    ),
    ("patch", "/collections/{collection_id}/members/{member_id}/comments/{comment_id}"): Rule(
        lambda w: Call(collection(w, member_id="m1", comment_id=w.fresh_comment()), json={"resolved": True}),
        other=404,
    ),
    ("delete", "/collections/{collection_id}/members/{member_id}/comments/{comment_id}"): Rule(
        lambda w: Call(collection(w, member_id="m1", comment_id=w.fresh_comment())), other=404
    ),
    ("post", "/collections/{collection_id}/members/{member_id}/annotations"): Rule(
        lambda w: Call({"collection_id": w.fresh_collection(), "member_id": "m1"}, json={"user": TEST_USER}),
        other=404,
    ),
    ("post", "/collections/{collection_id}/annotations"): Rule(
        lambda w: Call(collection(w), json={"user": TEST_USER}), other=404
    ),
    ("get", "/collections/{collection_id}/annotations"): Rule(lambda w: Call(collection(w)), other=404),
    ("get", "/collections/{collection_id}/agreement"): Rule(lambda w: Call(collection(w)), other=404),
    ("put", "/collections/{collection_id}/members/{member_id}/truth"): Rule(
        lambda w: Call(collection(w, member_id="m1"), files=w.truth_file()), other=404
    ),
    ("get", "/collections/{collection_id}/members/{member_id}/truth"): Rule(
        lambda w: Call(collection(w, member_id=w.with_truth())), other=404
    ),
    ("delete", "/collections/{collection_id}/members/{member_id}/truth"): Rule(
        lambda w: Call(collection(w, member_id=w.with_truth())), other=404
    ),
    ("post", "/collections/{collection_id}/runs"): Rule(
        lambda w: Call(collection(w), json={"converter": "nearest-neighbor", "members": ["m1"]}), other=404
    ),
    ("get", "/collections/{collection_id}/runs/{run_id}"): Rule(lambda w: Call(run(w)), other=404),
    ("get", "/collections/{collection_id}/runs/{run_id}/archive.{kind}"): Rule(
        lambda w: Call(run(w, kind="npz")), other=404
    ),
    ("get", "/collections/{collection_id}/runs/{run_id}/members/{member_id}"): Rule(
        lambda w: Call(run(w, member_id="m1")), other=404
    ),
    ("get", "/collections/{collection_id}/runs/{run_id}/members/{a}/to/{b}"): Rule(
        lambda w: Call(run(w, a="m1", b="m1")), other=404
    ),
}
PUBLIC_PATHS = {path for (_, path), rule in RULES.items() if rule.public} | {
    # the answers when an npm package is not installed (service/ui.py)
    f"{url}/{{path:path}}"
    for url in VENDOR_URLS.values()
}


@pytest.fixture(scope="module")
def world(module_processes, tmp_path_factory) -> World:
    lab = Lab(module_processes.api(tmp_path_factory.mktemp("access") / "data"))
    session_id = lab.new_session()
    curve = lab.add_curve(lab.owner, session_id)
    job = lab.refined(lab.owner, session_id)
    collection_id = lab.new_collection(lab.owner, session_id)
    run_id = lab.finished_run(lab.owner, collection_id)
    lab.api.client_for(World.grantee)
    return World(lab, session_id, curve, job["id"], "map_target_to_source.txt", collection_id, run_id)


def schema_routes(world: World) -> set[tuple[str, str]]:
    paths = world.lab.owner.get("/openapi.json").raise_for_status().json()["paths"]
    return {(method, path) for path, operations in paths.items() for method in operations}


def test_every_route_has_a_rule_and_every_rule_a_route(world):
    routes = schema_routes(world)
    assert not routes - set(RULES), f"routes without an access rule (add one to RULES): {sorted(routes - set(RULES))}"
    assert not set(RULES) - routes, f"rules of routes that are gone: {sorted(set(RULES) - routes)}"


@pytest.mark.parametrize("caller", CALLERS)
def test_the_access_matrix(world, caller):
    client = world.lab.caller(caller)
    wrong = []
    for method, path in sorted(schema_routes(world)):
        rule = RULES[(method, path)]
        call = rule.build(world)
        # streamed: a success's body is not read (an event stream's never ends)
        with client.stream(
            method, path.format(**call.path), json=call.json, params=call.params, files=call.files
        ) as response:
            if response.status_code >= 400:
                response.read()
            check_answer(wrong, response, method, path, rule.expected(caller), caller)
            if rule.new_token and response.status_code == 200:
                client.headers["Authorization"] = f"Bearer {json.loads(response.read())['token']}"
    assert not wrong, f"{caller}:\n" + "\n".join(wrong)


def check_answer(wrong: list[str], response, method: str, path: str, expected: int | str, caller: str) -> None:
    got = OK if 200 <= response.status_code < 300 else response.status_code
    if got != expected:
        said = f"{response.status_code} {response.text[:300] if response.status_code >= 400 else ''}"
        wrong.append(f"{method.upper()} {path}: expected {expected}, got {said}")
    elif response.status_code >= 400:
        ErrorBody.model_validate(response.json())
        if response.status_code == 401:
            assert response.headers["WWW-Authenticate"] == "Bearer"
        if response.status_code == 403 and caller == "other":  # a refusal does not tell who owns what
            assert TEST_USER not in response.json()["detail"], f"{method.upper()} {path}: {response.text}"


@pytest.mark.parametrize("path", ["/docs", "/redoc", "/openapi.json"])
def test_the_documentation_needs_credentials_too(world, path):
    assert world.lab.anonymous.get(path).status_code == 401
    assert world.lab.other.get(path).status_code == 200
    in_a_browser = world.lab.anonymous.get(path, headers={"Accept": "text/html,application/xhtml+xml,*/*;q=0.8"})
    if path == "/openapi.json":
        assert in_a_browser.status_code == 401
    else:  # the web UI's login page, not a JSON 401
        assert (in_a_browser.status_code, in_a_browser.headers["location"]) == (303, "/")


def test_the_ui_shell_is_public(world):
    for path in ("/", "/index.html", "/app.js", "/style.css", "/vendor/three/build/three.module.js"):
        assert world.lab.anonymous.get(path).status_code == 200, path


def test_an_anonymous_upload_is_refused_at_its_headers(world):
    """The credentials of a write are checked before its body is read: a refused upload stores nothing and
    the answer says why, whatever the body was."""
    before = world.lab.owner.get("/shapes").json()
    response = world.lab.anonymous.post("/shapes", content=b"not even multipart")
    assert response.status_code == 401 and response.json()["error"] == "unauthenticated"
    assert world.lab.owner.get("/shapes").json() == before


def test_every_route_that_is_not_public_asks_for_credentials(tmp_path):
    """The same promise from the app's route table, which also holds routes the schema leaves out (/docs)."""
    app = create_app(Settings(data_dir=tmp_path))
    unguarded = []
    for route in flat_routes(app.routes):
        if isinstance(route, Mount):
            assert route.name in {"ui"} | {f"vendor-{p}" for p in VENDOR_URLS}, f"unexpected mount {route.path}"
        elif not isinstance(route, APIRoute):
            unguarded.append(route.path)  # a plain Starlette route has no dependencies at all
        elif route.path not in PUBLIC_PATHS and not dependency_calls(route.dependant) & {current_user, bearer_user}:
            unguarded.append(route.path)
    assert not unguarded, f"routes that do not ask for credentials: {unguarded}"


def flat_routes(routes) -> list:
    """The routes, with those of included routers (which recent FastAPI keeps inside their router) listed too."""
    found = []
    for route in routes:
        included = getattr(route, "original_router", None)
        found += flat_routes(included.routes) if included is not None else [route]
    return found


def dependency_calls(dependant) -> set:
    calls = set()
    for sub in dependant.dependencies:
        calls |= {sub.call} | dependency_calls(sub)
    return calls
