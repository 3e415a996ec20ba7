"""Single sign-on's users (both engines): an OpenID Connect identity (issuer, subject) makes a user on its first
sign-in and finds it afterwards; a sign-in never takes over a user it did not make, nor comes back as a user an
admin removed; first sign-ins at the same moment make one user."""

from __future__ import annotations

import threading

import pytest
from sqlalchemy import select

from curvefm.errors import Forbidden
from curvefm.records import models as m
from curvefm.records.users import Users, usable_name

ISSUER = "https://idp.example.org/realms/lab"


def test_the_first_sign_in_makes_a_user_and_later_ones_find_it(db):
    users = Users(db)
    alice, made = users.sign_in(ISSUER, "f81d4fae-7dec", "alice")
    assert made and alice.name == "alice" and not alice.admin
    again, made_again = users.sign_in(ISSUER, "f81d4fae-7dec", "alice.renamed.at.the.idp")
    assert (again, made_again) == (alice, False)
    assert users.token_binding("alice") is not None  # login cookies can be bound to it
    assert users.authenticate(users.rotate("alice")) == alice  # a token for scripts
    elsewhere, made = users.sign_in("https://other.example.org", "f81d4fae-7dec", "alice")
    assert made and elsewhere.id != alice.id and elsewhere.name == "alice-2"


def test_a_sign_in_never_takes_over_a_user_it_did_not_make(db):
    users = Users(db)
    token = users.add("bob", admin=True)
    bob, _ = users.sign_in(ISSUER, "subject-1", "bob")
    assert bob.name == "bob-2" and not bob.admin
    assert users.authenticate(token).name == "bob"


def test_names_come_from_the_claim_made_usable():
    assert usable_name("Jane Doe <jane@uni.example>") == "Jane-Doe-jane-uni.example"
    assert usable_name("ü") == "user" and usable_name("..") == "user"
    assert len(usable_name("x" * 300) + "-1000") <= 64


def test_a_removed_user_does_not_come_back_by_signing_in(db):
    users = Users(db)
    carol, _ = users.sign_in(ISSUER, "subject-2", "carol")
    users.remove(carol.name)
    with pytest.raises(Forbidden, match="an admin removed"):
        users.sign_in(ISSUER, "subject-2", "carol")


def test_first_sign_ins_at_the_same_moment_make_one_user(db):
    users, barrier, found = Users(db), threading.Barrier(4), []

    def sign_in(subject: str) -> None:
        barrier.wait()
        found.append((subject, users.sign_in(ISSUER, subject, "dave")[0].id))

    threads = [threading.Thread(target=sign_in, args=(subject,)) for subject in ("s1", "s1", "s2", "s2")]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    with db.read() as conn:
        identities = dict(conn.execute(select(m.ExternalIdentity.subject, m.ExternalIdentity.user_id)).all())
    assert sorted(found) == sorted((subject, identities[subject]) for subject in ("s1", "s1", "s2", "s2"))
    assert {u.name for u in users.list()} == {"dave", "dave-2"}
