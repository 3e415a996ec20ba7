"""Single sign-on over HTTP: a real ``curvefm serve`` process signs people in at a real OpenID Connect provider
process on loopback (pyop over HTTPS, :mod:`support.oidc_provider`): the authorization code flow with PKCE, users
made at their first sign-in, a token for scripts; and what a person is told when the sign-in is not theirs, the
provider refuses it or hands out a broken ID token, or the provider is down: a 4xx or 503 saying why, never a 5xx,
and the client secret nowhere."""

from __future__ import annotations

import re
import subprocess
import sys
from urllib.parse import parse_qs, urlsplit

import httpx
import pytest
from support.oidc_provider import start_provider
from support.processes import free_port

from curvefm.access import audit_of, users_of
from curvefm.service.models import ErrorBody

LABEL = "Test IdP"
IN_A_BROWSER = {"Accept": "text/html,application/xhtml+xml,*/*;q=0.8"}
CALLBACK = "/auth/oidc/callback"


def sso_env(provider, label: str = LABEL) -> dict[str, str]:
    return {
        "CURVEFM_OIDC_ISSUER": provider.issuer,
        "CURVEFM_OIDC_CLIENT_ID": provider.client_id,
        "CURVEFM_OIDC_CLIENT_SECRET": provider.client_secret,
        "CURVEFM_OIDC_LABEL": label,
        "SSL_CERT_FILE": str(provider.ca),  # the provider's certificate is of the test's own CA
    }


def redirect_uris(port: int) -> list[str]:
    return [f"http://{host}:{port}{CALLBACK}" for host in ("127.0.0.1", "localhost")]


@pytest.fixture(scope="module")
def lab(module_processes, tmp_path_factory):
    """(API, provider): a server configured for the provider, which knows it as a client."""
    port = free_port()
    provider = start_provider(module_processes, free_port(), redirect_uris(port))
    data = tmp_path_factory.mktemp("sso") / "data"
    api = module_processes.api(data, env=sso_env(provider), port=port)
    return api, provider


def browser(api) -> httpx.Client:
    """A client without credentials that keeps its cookies, as a browser does."""
    return httpx.Client(base_url=api.url, timeout=60)


def begin(client: httpx.Client) -> str:
    """Start a sign-in; returns the provider's authorization URL it redirects to."""
    answer = client.get("/auth/oidc/login")
    assert answer.status_code == 302, answer.text
    return answer.headers["location"]


def sign_in(api, provider, user: str, client: httpx.Client | None = None) -> httpx.Client:
    """The whole flow for ``user``; returns the client, logged in."""
    client = client or browser(api)
    back = provider.sign_in(begin(client), user)
    answer = client.get(back)
    assert (answer.status_code, answer.headers.get("location")) == (303, "/"), answer.text
    return client


def assert_refused(answer: httpx.Response, status: int, says: str, secret: str) -> None:
    """A sign-in's failure: the status, a page saying why (or the JSON body), no secret, no login cookie."""
    assert answer.status_code == status, answer.text
    assert re.search(says, answer.text), answer.text
    assert secret not in answer.text
    assert "curvefm_login_" not in answer.headers.get("set-cookie", "")
    if answer.headers["content-type"].startswith("text/html"):
        assert "Signing in failed" in answer.text
    else:
        ErrorBody.model_validate(answer.json())


def test_the_page_learns_how_to_sign_in_before_anyone_is_logged_in(lab):
    api, _ = lab
    answer = httpx.get(f"{api.url}/auth/methods")
    assert answer.status_code == 200
    assert answer.json() == {"single_sign_on": {"label": LABEL, "login_url": "/auth/oidc/login"}}


def test_the_authorization_code_flow_with_pkce_signs_a_person_in(lab):
    api, provider = lab
    client = browser(api)
    redirect = client.get("/auth/oidc/login")
    assert redirect.status_code == 302
    assert re.fullmatch(
        r"curvefm_oidc=[^;]+; path=/auth/oidc; Max-Age=600; httponly; samesite=lax", redirect.headers["set-cookie"]
    )
    authorize = redirect.headers["location"]
    assert authorize.startswith(f"{provider.issuer}/authorize?")
    asked = {key: values[0] for key, values in parse_qs(urlsplit(authorize).query).items()}
    assert asked["response_type"] == "code" and asked["client_id"] == provider.client_id
    assert asked["redirect_uri"] == f"{api.url}{CALLBACK}"
    assert asked["code_challenge_method"] == "S256" and len(asked["code_challenge"]) == 43
    assert asked["nonce"] and asked["state"] and "openid" in asked["scope"].split()

    back = provider.sign_in(authorize, "ada")
    assert back.startswith(f"{api.url}{CALLBACK}?") and "code=" in back
    answer = client.get(back)
    assert (answer.status_code, answer.headers["location"]) == (303, "/")
    assert re.search(r"curvefm_login_\d+=.*HttpOnly.*SameSite=strict", answer.headers["set-cookie"], re.I)
    assert client.get("/auth/me").json() == {"name": "ada", "admin": False}
    assert client.get("/sessions").status_code == 200  # the cookie works as a token login's does

    ada = users_of(api.data_dir).get("ada")
    assert ada is not None and not ada.admin
    made = [e for e in audit_of(api.data_dir).read(user="ada") if e["action"] == "user.add"]
    assert [e["detail"] for e in made] == [{"single_sign_on": provider.issuer}]


def userinfo_requests(provider) -> int:
    return provider.log.read_text().count("/userinfo HTTP")


def test_a_second_sign_in_finds_the_user_of_the_first(lab):
    api, provider = lab
    asked = userinfo_requests(provider)
    first = sign_in(api, provider, "ada").get("/auth/me").json()
    assert userinfo_requests(provider) == asked  # the ID token named her
    before = {u.name for u in users_of(api.data_dir).list()}
    assert sign_in(api, provider, "ada").get("/auth/me").json() == first
    assert {u.name for u in users_of(api.data_dir).list()} == before


def test_without_a_name_claim_in_the_id_token_the_userinfo_names_the_user(lab):
    """grace has no preferred_username: her ID token names nobody, the userinfo has her e-mail address."""
    api, provider = lab
    asked = userinfo_requests(provider)
    assert sign_in(api, provider, "grace").get("/auth/me").json() == {"name": "grace.hopper", "admin": False}
    assert userinfo_requests(provider) == asked + 1


def test_a_signed_in_person_makes_a_token_for_scripts(lab):
    api, provider = lab
    client = sign_in(api, provider, "ada")
    assert client.post("/auth/token").status_code == 403  # a cookie write needs the service's Origin
    answer = client.post("/auth/token", headers={"Origin": api.url})
    assert answer.status_code == 200 and answer.headers["cache-control"] == "no-store"
    token = answer.json()["token"]
    script = httpx.get(f"{api.url}/auth/me", headers={"Authorization": f"Bearer {token}"})
    assert script.json() == {"name": "ada", "admin": False}
    assert client.get("/auth/me").status_code == 200  # this browser's cookie was renewed with the new token


def test_a_callback_replayed_or_from_another_browser_is_refused(lab):
    api, provider = lab
    client = browser(api)
    back = provider.sign_in(begin(client), "ada")
    stranger = browser(api).get(back, headers=IN_A_BROWSER)  # no state cookie: a sign-in begun elsewhere
    assert_refused(stranger, 400, "this sign-in is unknown here", provider.client_secret)
    assert client.get(back).status_code == 303
    assert_refused(client.get(back, headers=IN_A_BROWSER), 400, "unknown here", provider.client_secret)
    assert_refused(browser(api).get(CALLBACK), 400, "sends a person back after signing in", provider.client_secret)


def test_starting_again_and_again_keeps_one_sign_in_under_way(lab):
    """Each start replaces the browser's sign-in under way: the state cookie stays small, the latest one works."""
    api, provider = lab
    client = browser(api)
    starts = [begin(client) for _ in range(30)]
    assert len(client.cookies["curvefm_oidc"]) < 1000
    assert_refused(client.get(provider.sign_in(starts[0], "ada")), 400, "unknown here", provider.client_secret)
    assert client.get(provider.sign_in(starts[-1], "ada")).status_code == 303


def test_a_refusal_of_the_provider_is_a_401_saying_so(lab):
    api, provider = lab
    client = browser(api)
    state = parse_qs(urlsplit(begin(client)).query)["state"][0]
    answer = client.get(CALLBACK, params={"error": "access_denied", "error_description": "not today", "state": state})
    assert_refused(answer, 401, "refused the sign-in: access_denied: not today", provider.client_secret)


REFUSED = "ID token of the provider .* was refused: "


@pytest.mark.parametrize(
    ("mode", "says"),
    [
        ("audience", REFUSED + "missing_claim: Missing claim: .*azp"),  # aud is not us, and no azp says we may
        ("signature", REFUSED + "bad_signature"),
        ("expired", REFUSED + "expired_token"),
        ("long-subject", "gave no subject of 1 to 255 characters"),
    ],
)
def test_a_broken_id_token_is_refused(lab, mode, says):
    api, provider = lab
    provider.tamper(mode)
    try:
        client = browser(api)
        answer = client.get(provider.sign_in(begin(client), "ada"), headers=IN_A_BROWSER)
    finally:
        provider.tamper("none")
    assert_refused(answer, 401, says, provider.client_secret)
    assert client.get("/auth/me").status_code == 401


def test_a_provider_that_is_down_or_names_another_issuer_is_a_503(processes, tmp_path):
    """Down before the first sign-in (discovery fails); up, but set up with an issuer URL other than the one it
    states (a trailing slash); then down between its sign-in form and the code's exchange (the token endpoint
    fails)."""
    port, provider_port = free_port(), free_port()
    unstarted = {
        "CURVEFM_OIDC_ISSUER": f"https://127.0.0.1:{provider_port}",
        "CURVEFM_OIDC_CLIENT_ID": "curvefm-test",
        "CURVEFM_OIDC_CLIENT_SECRET": "never-shown-secret",
    }
    api = processes.api(tmp_path / "data", env=unstarted, port=port)
    client = browser(api)
    assert_refused(client.get("/auth/oidc/login"), 503, "did not answer", "never-shown-secret")
    assert_refused(client.get("/auth/oidc/login", headers=IN_A_BROWSER), 503, "did not answer", "never-shown-secret")

    provider = start_provider(processes, provider_port, redirect_uris(port))
    processes.kill(api.process)  # started again, with the provider's client credentials and CA
    slashed = {**sso_env(provider), "CURVEFM_OIDC_ISSUER": provider.issuer + "/"}
    api = processes.api(tmp_path / "data", env=slashed, port=port)
    says = f"says its issuer is '{provider.issuer}'"
    assert_refused(browser(api).get("/auth/oidc/login"), 503, says, provider.client_secret)
    processes.kill(api.process)
    api = processes.api(tmp_path / "data", env=sso_env(provider), port=port)
    client = browser(api)
    back = provider.sign_in(begin(client), "ada")
    processes.kill(provider.process)
    assert_refused(client.get(back, headers=IN_A_BROWSER), 503, "did not answer", provider.client_secret)
    assert client.get("/auth/me").status_code == 401


def test_the_server_log_holds_no_secret_and_no_code(lab):
    """Runs after the sign-ins above: the client secret was never logged, nor a code or state of a callback."""
    api, provider = lab
    log = api.log.read_text()
    assert CALLBACK in log and provider.client_secret not in log
    assert not re.search(r"[?&](code|state)=(?!\[redacted\])", log)


def test_the_command_line_makes_a_signed_in_person_an_admin_and_takes_it_away(lab):
    """A sign-in makes no admin; ``curvefm users admin NAME`` makes that user one, effective at their next request
    (their login cookie reads the audit log), ``--revoke`` takes it away; both audited, an unknown name refused."""
    api, provider = lab
    client = sign_in(api, provider, "ada")
    assert client.get("/audit").status_code == 403

    def users_admin(*args: str) -> subprocess.CompletedProcess:
        command = [sys.executable, "-m", "curvefm.cli", "users", "admin", *args, "--data", str(api.data_dir)]
        return subprocess.run(command, capture_output=True, text=True)

    made = users_admin("ada")
    assert made.returncode == 0 and "ada is an admin now" in made.stdout, made.stderr
    assert client.get("/auth/me").json() == {"name": "ada", "admin": True}
    assert client.get("/audit").status_code == 200
    assert users_admin("ada", "--revoke").returncode == 0
    assert client.get("/auth/me").json() == {"name": "ada", "admin": False}
    assert client.get("/audit").status_code == 403
    refused = users_admin("nobody")
    assert refused.returncode == 2 and "no user 'nobody'" in refused.stderr

    changes = [(e["user"], e["detail"]) for e in audit_of(api.data_dir).read() if e["action"] == "user.admin"]
    assert changes[-2:] == [("cli", {"admin": True, "was": False}), ("cli", {"admin": False, "was": True})]
