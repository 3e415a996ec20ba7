"""Logging in as a person does, in real Chromium against a real ``curvefm serve`` on an empty data directory: the
server makes its local admin and prints a login URL; the page trades the URL's token for an HttpOnly,
SameSite=Strict cookie and takes the token out of the address bar; a page of another origin cannot write with
that cookie (403), nor can a request without an Origin; logging out, rotating the token or a forged cookie ends
the login. The page shows who is logged in, and shares a session through its Sharing select."""

from __future__ import annotations

import json
import re
import threading
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

import httpx
import pytest
from support.lab import Lab
from support.processes import add_user, free_port
from support.shapes import ellipsoid, off_bytes
from support.ui import VIEWPORT, open_session

from curvefm.access import users_of
from curvefm.service.models import ErrorBody

LOGIN_URL = re.compile(r"(http://127\.0\.0\.1:\d+)/\?token=(cfm_[A-Za-z0-9_-]+)")
FOREIGN_PAGE = """<!doctype html><form id="upload" method="post" action="{api}/shapes" enctype="multipart/form-data">
<input type="file" name="file" id="file"></form>"""
UPLOAD_JS = """async (text) => {
  const form = new FormData();
  form.append("file", new Blob([text]), "from-the-page.off");
  const response = await fetch("/shapes", { method: "POST", body: form });
  return response.status;
}"""


@pytest.fixture(scope="module")
def server(module_processes, tmp_path_factory):
    """A server whose data directory had no user: it printed the login URL of the admin it made."""
    api = module_processes.api(tmp_path_factory.mktemp("login") / "data", user=None)
    found = LOGIN_URL.search(api.log.read_text())
    assert found, f"no login URL in the server's output:\n{api.log.read_text()[-2000:]}"
    assert found.group(1) == api.url
    api.login_url, api.printed_token = found.group(0), found.group(2)
    api.client.headers["Authorization"] = f"Bearer {api.printed_token}"
    return api


@pytest.fixture(scope="module")
def foreign_origin(server):
    """A web page of another origin (same host, another port: the same *site*, so the browser does send a
    SameSite=Strict cookie with its requests, and only the Origin check stands in the way)."""
    page = FOREIGN_PAGE.format(api=server.url).encode()

    class Handler(BaseHTTPRequestHandler):
        def do_GET(self):  # noqa: N802 (the name http.server calls)
            self.send_response(200)
            self.send_header("Content-Type", "text/html")
            self.end_headers()
            self.wfile.write(page)

        def log_message(self, *args):
            pass

    httpd = ThreadingHTTPServer(("127.0.0.1", free_port()), Handler)
    threading.Thread(target=httpd.serve_forever, daemon=True).start()
    yield f"http://127.0.0.1:{httpd.server_port}"
    httpd.shutdown()


def login_cookie(context) -> dict:
    cookies = [c for c in context.cookies() if c["name"].startswith("curvefm_login_")]
    assert len(cookies) == 1, context.cookies()
    return cookies[0]


def shape_count(server) -> int:
    return len(server.client.get("/shapes").raise_for_status().json())


def logged_in_cookie(server) -> dict:
    """The login cookie, got as the page gets it."""
    response = server.client.post("/auth/login").raise_for_status()
    name, value = response.headers["set-cookie"].split(";")[0].split("=", 1)
    return {"name": name, "value": value}


def cookie_client(server, cookie: dict, **headers) -> httpx.Client:
    return httpx.Client(base_url=server.url, headers={"Cookie": f"{cookie['name']}={cookie['value']}", **headers})


def expect(response, status: int, kind: str, *words: str) -> None:
    assert response.status_code == status, response.text
    body = ErrorBody.model_validate(response.json())
    assert body.error == kind and all(word in body.detail for word in words), body


def test_the_local_admin_is_the_only_user(server):
    assert [(u.name, u.admin) for u in users_of(server.data_dir).list()] == [("admin", True)]


def test_login_url_cookie_origin_check_and_logout(server, browser, foreign_origin):
    context = browser.new_context(viewport=VIEWPORT)
    page = context.new_page()
    page.goto(server.login_url)
    page.wait_for_selector("#user-name:has-text('admin (admin)')")
    assert "token" not in page.url and page.url.startswith(server.url)

    cookie = login_cookie(context)
    assert (cookie["httpOnly"], cookie["sameSite"], cookie["path"]) == (True, "Strict", "/")
    assert server.printed_token not in cookie["value"] and cookie["name"] not in page.evaluate("document.cookie")
    assert page.evaluate(UPLOAD_JS, off_bytes(ellipsoid(6, 12)).decode()) == 201  # the page's own writes pass

    before = shape_count(server)
    foreign = context.new_page()
    foreign.goto(f"{foreign_origin}/")
    foreign.set_input_files(
        "#file", files=[{"name": "e.off", "mimeType": "text/plain", "buffer": off_bytes(ellipsoid(7, 14))}]
    )
    with foreign.expect_navigation():
        foreign.evaluate("document.getElementById('upload').submit()")
    answer = json.loads(foreign.inner_text("body"))
    assert answer["error"] == "forbidden" and foreign_origin in answer["detail"], answer
    assert shape_count(server) == before

    page.click("#logout-button")
    page.wait_for_selector("#login-needed", state="visible")
    assert "login URL" in page.inner_text("#login-needed")
    assert not [c for c in context.cookies() if c["name"] == cookie["name"]]
    assert page.evaluate("fetch('/auth/me').then((r) => r.status)") == 401
    context.close()
    stolen = {"Cookie": f"{cookie['name']}={cookie['value']}"}  # a copy of the cookie made before the logout
    assert httpx.get(f"{server.url}/auth/me", headers=stolen).status_code == 401


def test_cookie_writes_need_this_services_origin(server):
    cookie = logged_in_cookie(server)
    upload = {"file": ("e.off", off_bytes(ellipsoid(5, 10)))}
    before = shape_count(server)
    expect(
        cookie_client(server, cookie, Origin="http://evil.example").post("/shapes", files=upload),
        403,
        "forbidden",
        "evil.example",
    )
    expect(cookie_client(server, cookie).post("/shapes", files=upload), 403, "forbidden", "none")
    assert shape_count(server) == before
    own = cookie_client(server, cookie, Origin=server.url).post("/shapes", files=upload)
    assert own.status_code == 201 and own.json()["uploaders"] == ["admin"]


def test_a_forged_or_stale_cookie_is_refused(server):
    cookie = logged_in_cookie(server)
    forged = dict(cookie, value=cookie["value"][:-2] + ("AA" if not cookie["value"].endswith("AA") else "BB"))
    expect(cookie_client(server, forged).get("/auth/me"), 401, "unauthenticated", "login")
    assert cookie_client(server, cookie).get("/auth/me").json()["name"] == "admin"
    server.client.headers["Authorization"] = f"Bearer {users_of(server.data_dir).rotate('admin')}"
    expect(cookie_client(server, cookie).get("/auth/me"), 401, "unauthenticated", "changed")


def test_a_wrong_token_in_the_url_says_how_to_log_in(server, browser):
    context = browser.new_context(viewport=VIEWPORT)
    page = context.new_page()
    page.goto(f"{server.url}/?token=cfm_{'x' * 43}")
    page.wait_for_selector("#login-needed", state="visible")
    assert "token" not in page.url and not context.cookies()
    context.close()


def test_the_token_stays_out_of_the_access_log(server):
    assert httpx.get(server.login_url).status_code == 200  # the page, whose URL holds the token
    log = server.log.read_text()
    assert log.count(server.printed_token) == 1  # the printed login URL, and nothing after it
    assert "GET /?token=[redacted]" in log


def test_the_owner_shares_a_session_from_the_page_and_another_user_sees_it_read_only(server, browser):
    lab = Lab(server)  # its owner is the admin the server made
    session_id = lab.new_session(name="shared from the page")
    owner = browser.new_context(viewport=VIEWPORT).new_page()
    open_session(owner, server.url, session_id, token=server.client.headers["Authorization"].split()[-1])
    assert owner.inner_text("#user-name") == "admin (admin)"
    owner.click("#pair-panel summary")  # the Shapes & session panel is folded while a session is open
    assert owner.is_enabled("#sharing-select") and owner.input_value("#sharing-select") == "private"
    owner.select_option("#sharing-select", "read")
    owner.wait_for_selector(".toast:has-text('every user may read it')")
    assert server.client.get(f"/sessions/{session_id}").json()["sharing"] == "read"

    reader = browser.new_context(viewport=VIEWPORT).new_page()
    open_session(reader, server.url, session_id, token=add_user(server.data_dir, "bob"))
    assert reader.inner_text("#user-name") == "bob"
    assert "read-only (shared by admin)" in reader.inner_text("#session-title")
    assert reader.is_disabled("#sharing-select") and reader.input_value("#sharing-select") == "read"
    owner.context.close()
    reader.context.close()
