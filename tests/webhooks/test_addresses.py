"""Which URLs a webhook may post to: internal addresses refused unless allowed, at registration (literal
addresses and local names) and before each delivery (what a name resolves to)."""

from __future__ import annotations

import pytest

from curvefm.errors import InvalidInput
from curvefm.webhooks import check_resolved, checked_url

SETTING = "CURVEFM_WEBHOOK_ALLOW_PRIVATE"
INTERNAL = [
    "http://127.0.0.1:8000/hook",
    "http://localhost/hook",
    "http://api.localhost/hook",
    "http://10.1.2.3/hook",
    "http://192.168.0.10/hook",
    "http://172.16.5.5/hook",
    "http://169.254.169.254/latest/meta-data",  # a cloud's metadata service
    "http://[::1]/hook",
    "http://[fd00::1]/hook",
    "http://[::ffff:127.0.0.1]/hook",
    "http://0.0.0.0/hook",
    "http://224.0.0.1/hook",
]


@pytest.mark.parametrize("url", INTERNAL)
def test_an_internal_address_is_refused_unless_allowed(url):
    with pytest.raises(InvalidInput, match=SETTING):
        checked_url(url, allow_private=False, setting=SETTING)
    assert checked_url(url, allow_private=True, setting=SETTING) == url


@pytest.mark.parametrize("url", ["https://lab.example/hook", "http://93.184.215.14:8080/x?a=1"])
def test_a_public_address_is_accepted(url):
    assert checked_url(f" {url} ", allow_private=False, setting=SETTING) == url


@pytest.mark.parametrize(
    "url", ["ftp://lab.example/x", "file:///etc/passwd", "https:///nohost", "lab.example/x", "https://a:b@lab.example/"]
)
def test_what_is_not_an_http_url_is_refused(url):
    with pytest.raises(InvalidInput):
        checked_url(url, allow_private=True, setting=SETTING)


def test_a_name_that_resolves_to_loopback_is_refused_before_a_delivery():
    """A name passes registration (its addresses may change); the delivery resolves it and refuses."""
    url = "http://localhost:9/hook"
    with pytest.raises(InvalidInput, match=SETTING):
        check_resolved(url, allow_private=False, setting=SETTING)
    check_resolved(url, allow_private=True, setting=SETTING)
    with pytest.raises(InvalidInput, match="does not resolve"):
        check_resolved("http://no-such-host.invalid/hook", allow_private=False, setting=SETTING)
