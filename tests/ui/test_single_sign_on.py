"""Single sign-on as a person does it, in real Chromium: the page of a real ``curvefm serve`` offers "Sign in with
..." (its OpenID Connect provider configured), the browser goes to a real provider process on loopback (pyop over
HTTPS, :mod:`support.oidc_provider`), signs in through its form and comes back to the page logged in, as a user
made at that first sign-in; then makes a token for scripts, and logs out. The page is at ``localhost`` and the
provider at ``127.0.0.1``: two sites, as a lab's service and its university's provider are, so the browser's
cross-site cookie rules apply to the return."""

from __future__ import annotations

import httpx
import pytest
from support.oidc_provider import USERS, start_provider
from support.processes import free_port
from support.ui import VIEWPORT, screenshot

from curvefm.access import users_of

LABEL = "Test IdP"


@pytest.fixture(scope="module")
def server(module_processes, tmp_path_factory):
    """(the page's URL, the API, the provider)."""
    port = free_port()
    callbacks = [f"http://{host}:{port}/auth/oidc/callback" for host in ("localhost", "127.0.0.1")]
    provider = start_provider(module_processes, free_port(), callbacks)
    env = {
        "CURVEFM_OIDC_ISSUER": provider.issuer,
        "CURVEFM_OIDC_CLIENT_ID": provider.client_id,
        "CURVEFM_OIDC_CLIENT_SECRET": provider.client_secret,
        "CURVEFM_OIDC_LABEL": LABEL,
        "SSL_CERT_FILE": str(provider.ca),
    }
    api = module_processes.api(tmp_path_factory.mktemp("sso-ui") / "data", env=env, port=port)
    return f"http://localhost:{port}", api, provider


def test_signing_in_at_the_provider_comes_back_logged_in(server, browser):
    url, api, provider = server
    assert users_of(api.data_dir).get("ada") is None
    # the browser does not know the test's CA: only the provider's certificate is of it
    context = browser.new_context(viewport=VIEWPORT, ignore_https_errors=True)
    page = context.new_page()
    page.goto(f"{url}/")
    button = page.locator("#sso-login")
    button.wait_for(state="visible", timeout=30_000)
    assert button.inner_text() == f"Sign in with {LABEL}"
    assert page.locator("#user-box").is_hidden()
    screenshot(page, "single-sign-on-offered")

    button.click()
    page.wait_for_url(f"{provider.issuer}/authorize?*", timeout=30_000)
    page.fill("#username", "ada")
    page.fill("#password", USERS["ada"]["password"])
    page.click("#sign-in")
    page.wait_for_url(f"{url}/", timeout=30_000)
    page.locator("#user-box").wait_for(state="visible", timeout=30_000)
    assert page.locator("#user-name").inner_text() == "ada"
    assert page.locator("#login-needed").is_hidden()
    assert "code=" not in page.url and "state=" not in page.url
    screenshot(page, "single-sign-on-logged-in")
    ada = users_of(api.data_dir).get("ada")
    assert ada is not None and not ada.admin

    page.once("dialog", lambda dialog: dialog.accept())
    page.click("#new-token-button")
    page.locator("#token-box").wait_for(state="visible")
    token = page.locator("#new-token").inner_text()
    mine = httpx.get(f"{api.url}/auth/me", headers={"Authorization": f"Bearer {token}"})
    assert mine.json() == {"name": "ada", "admin": False}
    page.click("#token-done")
    assert page.locator("#token-box").is_hidden() and page.locator("#new-token").inner_text() == ""
    page.reload()
    page.locator("#user-box").wait_for(state="visible", timeout=30_000)  # the login cookie was renewed
    page.click("#logout-button")
    page.locator("#sso-login").wait_for(state="visible", timeout=30_000)  # offered again
    assert page.locator("#user-box").is_hidden()
    context.close()


def test_a_failed_sign_in_is_a_page_saying_why(server, browser):
    url, _, provider = server
    context = browser.new_context(viewport=VIEWPORT)
    page = context.new_page()
    answer = page.goto(f"{url}/auth/oidc/callback?code=made-up&state=made-up")
    assert answer.status == 400
    message = page.locator("#sign-in-failed").inner_text()
    assert "this sign-in is unknown here" in message and provider.client_secret not in page.content()
    page.click("text=Back to curvefm")
    page.locator("#sso-login").wait_for(state="visible", timeout=30_000)
    context.close()
