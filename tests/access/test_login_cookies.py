"""The login cookie's value (service/login.py) on a real data directory: good until it expires, its user's token
is rotated or the user removed; anything not signed by this data directory's key logs nobody in."""

from __future__ import annotations

import base64
import json
from pathlib import Path

import pytest

from curvefm.access import Users, signing_key, users_of
from curvefm.service.login import LoginCookies


@pytest.fixture
def users(tmp_path) -> Users:
    users = users_of(tmp_path)
    users.add("alice")
    users.add("root", admin=True)
    return users


def cookies(users: Users, ttl_s: float = 3600, data=None) -> LoginCookies:
    return LoginCookies(signing_key(data or Path(users.db.url.database).parent), users, ttl_s)


def test_a_cookie_logs_its_user_in(users):
    jar = cookies(users)
    assert jar.verify(jar.issue(users.get("alice"))) == users.get("alice")
    assert jar.verify(jar.issue(users.get("root"))).admin


def test_an_expired_cookie_is_refused(users):
    jar = cookies(users, ttl_s=-1)
    assert jar.verify(jar.issue(users.get("alice"))) is None


def test_rotating_the_token_or_removing_the_user_ends_the_cookie(users):
    jar = cookies(users)
    alice, root = jar.issue(users.get("alice")), jar.issue(users.get("root"))
    users.rotate("alice")
    users.remove("root")
    assert jar.verify(alice) is None and jar.verify(root) is None
    assert jar.verify(jar.issue(users.get("alice"))).name == "alice"  # a new login works


def test_ending_logins_refuses_the_cookies_made_before_and_keeps_the_token(users):
    jar = cookies(users)
    first, second = jar.issue(users.get("alice")), jar.issue(users.get("alice"))
    root = jar.issue(users.get("root"))
    users.end_logins("alice")
    assert jar.verify(first) is None and jar.verify(second) is None
    assert jar.verify(root).name == "root"  # another user's logins go on
    assert jar.verify(jar.issue(users.get("alice"))).name == "alice"  # a new login works


def test_a_cookie_of_another_data_directory_is_refused(users, tmp_path):
    elsewhere = users_of(tmp_path / "elsewhere")
    elsewhere.add("alice")
    foreign = cookies(elsewhere, data=tmp_path / "elsewhere").issue(elsewhere.get("alice"))
    assert cookies(users).verify(foreign) is None


def test_a_payload_changed_without_the_key_is_refused(users):
    jar = cookies(users)
    payload, signature = jar.issue(users.get("alice")).split(".")
    name, binding, expiry = json.loads(base64.urlsafe_b64decode(payload + "=" * (-len(payload) % 4)))
    changed = base64.urlsafe_b64encode(json.dumps(["root", binding, expiry]).encode()).rstrip(b"=").decode()
    assert jar.verify(f"{changed}.{signature}") is None


@pytest.mark.parametrize("value", ["", ".", "a.b.c", "abc.", "é.é", "x" * 10_000 + "." + "y"])
def test_garbage_is_refused(users, value):
    assert cookies(users).verify(value) is None
