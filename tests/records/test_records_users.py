"""Users and tokens in the database (both engines): the operations of the old UserStore, and stable ids."""

from __future__ import annotations

import pytest
from support.records import repositories, session_record, shape_id

from curvefm.errors import Conflict, InvalidInput, NotFound
from curvefm.records.common import Viewer
from curvefm.records.users import REMOVED, Users


def test_add_authenticate_rotate_remove(db):
    users = Users(db)
    assert users.is_empty()
    token = users.add("alice")
    admin_token = users.add("root", admin=True)
    alice = users.authenticate(token)
    assert alice is not None and alice.name == "alice" and not alice.admin
    assert users.authenticate(admin_token).admin
    assert users.authenticate("cfm_" + "x" * 40) is None
    assert users.authenticate("not a token") is None
    assert [u.name for u in users.list()] == ["alice", "root"]
    binding = users.token_binding("alice")
    new = users.rotate("alice")
    assert users.authenticate(token) is None and users.authenticate(new).id == alice.id
    assert users.token_binding("alice") != binding
    users.remove("alice")
    assert users.authenticate(new) is None and users.get("alice") is None and users.token_binding("alice") is None
    with pytest.raises(NotFound):
        users.remove("alice")
    with pytest.raises(NotFound):
        users.rotate("nobody")


def test_names_are_checked_and_unique(db):
    users = Users(db)
    users.add("bob")
    with pytest.raises(Conflict):
        users.add("bob")
    for bad in ("", "a/b", "..", "x" * 65, "with space"):
        with pytest.raises(InvalidInput):
            users.add(bad)


def test_a_user_added_again_under_a_removed_name_is_another_user(db):
    """The old store knew users by name only: a re-added name read the old user's private sessions."""
    repo = repositories(db)
    users, shapes, sessions = repo["users"], repo["shapes"], repo["sessions"]
    users.add("carol")
    old = users.get("carol")
    a, b = shape_id(), shape_id()
    shapes.add(a, 10, old.id)
    shapes.add(b, 10, old.id)
    private = session_record(a, b, owner="carol")
    sessions.create(private)
    users.remove("carol")
    users.add("carol")
    new = users.get("carol")
    assert new.id != old.id
    assert sessions.page(Viewer(new.id)).total == 0
    assert sessions.read(private.id).owner == "carol" + REMOVED  # a name no user can have
    assert sessions.page(Viewer(None, admin=True)).total == 1


def test_ensure_local_admin_once(db):
    users = Users(db)
    token = users.ensure_local_admin("admin")
    assert token and users.authenticate(token).admin
    assert users.ensure_local_admin("admin") is None
    assert len(users.list()) == 1
