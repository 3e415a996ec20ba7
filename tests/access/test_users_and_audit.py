"""Users, tokens and the audit log in the data directory's database (its SQLite file), changed by real concurrent
processes; the login-cookie key on a real file."""

import sqlite3
import subprocess
import sys
import textwrap
import time

import pytest

from curvefm.access import TOKEN_PREFIX, User, audit_of, signing_key, users_of
from curvefm.errors import CurvefmError


def run_together(data, script: str, *process_args: str) -> list[str]:
    """Run ``script`` (``data``, ``args`` and ``go`` are defined for it) in one process per argument, all
    released at the same moment by a start file; returns their outputs."""
    go = data / "go"
    prelude = f"import sys, os, time\ndata, args, go = {str(data)!r}, sys.argv[1:], {str(go)!r}\n"
    wait = "while not os.path.exists(go): time.sleep(0.001)\n"
    processes = [
        subprocess.Popen(
            [sys.executable, "-c", prelude + textwrap.dedent(script).replace("#GO\n", wait), arg],
            stdout=subprocess.PIPE,
            text=True,
        )
        for arg in process_args
    ]
    time.sleep(1.0)  # let both finish importing
    go.touch()
    outputs = [p.communicate(timeout=120)[0] for p in processes]
    assert [p.returncode for p in processes] == [0] * len(processes)
    return outputs


# -- users ---------------------------------------------------------------------------------------------------
def test_a_token_authenticates_until_rotated_or_removed(tmp_path):
    users = users_of(tmp_path)
    assert users.is_empty() and users.authenticate(TOKEN_PREFIX + "x" * 43) is None
    token = users.add("alice")
    assert token.startswith(TOKEN_PREFIX) and len(token) > 40
    alice = users.authenticate(token)
    assert alice == User(id=alice.id, name="alice", admin=False, created_at=alice.created_at)
    assert not users.is_empty()
    new = users.rotate("alice")
    assert users.authenticate(token) is None and users.authenticate(new).name == "alice"
    users.remove("alice")
    assert users.authenticate(new) is None and users.is_empty()


@pytest.mark.parametrize("token", ["", "cfm_", "not-a-token", "cfm_" + "A" * 500, None, 42])
def test_malformed_tokens_are_refused(tmp_path, token):
    users = users_of(tmp_path)
    users.add("alice")
    assert users.authenticate(token) is None


def database_rows(data, query: str) -> list[tuple]:
    """Rows of the data directory's SQLite database, read by sqlite3 itself (not through curvefm)."""
    with sqlite3.connect(data / "curvefm.db") as conn:
        return conn.execute(query).fetchall()


def test_the_database_holds_hashes_not_tokens(tmp_path):
    users = users_of(tmp_path)
    tokens = [users.add("alice", admin=True), users.add("bob")]
    rows = database_rows(tmp_path, "SELECT name, token_sha256 FROM users ORDER BY id")
    text = repr(rows)
    assert not any(token in text or token[len(TOKEN_PREFIX) :] in text for token in tokens)
    assert [name for name, _ in rows] == ["alice", "bob"] and all(len(digest) == 64 for _, digest in rows)
    assert [(u.name, u.admin) for u in users.list()] == [("alice", True), ("bob", False)]
    assert set(vars(users.list()[0])) == {"id", "name", "admin", "created_at"}


def test_a_user_added_again_under_an_old_name_is_another_user(tmp_path):
    users = users_of(tmp_path)
    users.add("alice")
    old = users.get("alice")
    users.remove("alice")
    token = users.add("alice")
    new = users.authenticate(token)
    assert new.name == "alice" and new.id != old.id
    # the old row stays (what it owned keeps an owner nobody inherits), without its token hash
    assert database_rows(tmp_path, f"SELECT token_sha256, removed_at IS NOT NULL FROM users WHERE id = {old.id}") == [
        (None, 1)
    ]


@pytest.mark.parametrize("name", ["", "a" * 65, "a b", "élodie", "a/b", "..", "."])
def test_bad_names_are_refused(tmp_path, name):
    with pytest.raises(CurvefmError) as error:
        users_of(tmp_path).add(name)
    assert error.value.code == "invalid" and "user name" in error.value.message


def test_names_of_the_allowed_characters_are_accepted(tmp_path):
    users = users_of(tmp_path)
    for name in ["a" * 64, "Jo.Smith-2_x", "7"]:
        users.add(name)
    assert sorted(user.name for user in users.list()) == sorted(["a" * 64, "Jo.Smith-2_x", "7"])


def test_duplicates_and_unknown_users_are_errors_of_their_kind(tmp_path):
    users = users_of(tmp_path)
    users.add("alice")
    with pytest.raises(CurvefmError) as duplicate:
        users.add("alice", admin=True)
    assert duplicate.value.code == "conflict"
    for change in (users.remove, users.rotate):
        with pytest.raises(CurvefmError) as unknown:
            change("bob")
        assert unknown.value.code == "not_found" and "'bob'" in unknown.value.message


def test_a_local_admin_is_made_only_when_there_is_no_user(tmp_path):
    users = users_of(tmp_path)
    token = users.ensure_local_admin()
    admin = users.list()[0]
    assert users.authenticate(token) == User(admin.id, "admin", True, admin.created_at)
    assert users.ensure_local_admin() is None
    other = users_of(tmp_path / "other")
    other.add("alice")
    assert other.ensure_local_admin() is None and [u.name for u in other.list()] == ["alice"]


def test_two_processes_adding_users_at_once_lose_none(tmp_path):
    script = """
        from curvefm.access import users_of
        users = users_of(data)
        #GO
        for i in range(20):
            print(users.add(f"{args[0]}{i}"))
    """
    outputs = run_together(tmp_path, script, "a", "b")
    users = users_of(tmp_path)
    assert len(users.list()) == 40
    tokens = [line for output in outputs for line in output.split()]
    assert sorted(users.authenticate(t).name for t in tokens) == sorted(f"{p}{i}" for p in "ab" for i in range(20))


def test_changes_by_another_process_take_effect_at_once(tmp_path):
    users = users_of(tmp_path)
    token = users.add("alice")
    assert users.authenticate(token).name == "alice"
    script = "from curvefm.access import users_of\nu = users_of(data)\nu.remove('alice')\nprint(u.add('bob'))\n"
    done = subprocess.run(
        [sys.executable, "-c", f"data = {str(tmp_path)!r}\n" + script], capture_output=True, text=True, check=True
    )
    assert users.authenticate(token) is None
    assert users.authenticate(done.stdout.strip()).name == "bob"


def test_a_token_binding_names_the_current_token_only(tmp_path):
    users = users_of(tmp_path)
    token = users.add("alice")
    before = users.token_binding("alice")
    assert before and token not in before and users.get("alice").name == "alice"
    users.rotate("alice")
    assert users.token_binding("alice") not in (None, before)
    users.remove("alice")
    assert users.token_binding("alice") is None and users.get("alice") is None


# -- the signing key -----------------------------------------------------------------------------------------
def test_the_signing_key_is_made_once_private_and_shared_by_processes(tmp_path):
    script = """
        from curvefm.access import signing_key
        #GO
        print(signing_key(data).hex())
    """
    keys = {output.strip() for output in run_together(tmp_path, script, "a", "b", "c")}
    assert len(keys) == 1 and signing_key(tmp_path).hex() in keys
    path = tmp_path / "access" / "signing.key"
    assert path.stat().st_mode & 0o777 == 0o600 and len(path.read_bytes()) == 32
    assert [p.name for p in path.parent.iterdir() if p.name.startswith(".signing")] == []  # no leftovers


def test_a_damaged_signing_key_is_an_internal_error(tmp_path):
    signing_key(tmp_path)
    (tmp_path / "access" / "signing.key").write_bytes(b"short")
    with pytest.raises(CurvefmError) as error:
        signing_key(tmp_path)
    assert error.value.code == "internal" and str(tmp_path) not in error.value.message


# -- audit log -----------------------------------------------------------------------------------------------
def test_the_audit_log_reads_the_last_events_with_filters(tmp_path):
    log = audit_of(tmp_path)
    assert log.read() == []
    for i in range(10):
        log.record("alice" if i % 2 else "bob", "session.create", f"s{i}", {"n": i})
    assert [e["target"] for e in log.read(limit=3)] == ["s7", "s8", "s9"]
    assert [e["target"] for e in log.read(limit=2, user="bob")] == ["s6", "s8"]
    event = log.read(limit=1)[0]
    assert set(event) == {"time", "user", "action", "target", "detail"} and event["detail"] == {"n": 9}
    assert log.read(since="2000-01-01T00:00:00") == log.read(limit=100) and len(log.read()) == 10
    everything = log.read()
    assert log.read(since=everything[4]["time"]) == [e for e in everything if e["time"] >= everything[4]["time"]]
    assert log.read(since=event["time"])[-1] == event
    assert log.read(since="2999-01-01T00:00:00+00:00") == []


def test_the_audit_log_pages_newest_first_with_the_total(tmp_path):
    log = audit_of(tmp_path)
    for i in range(50):
        log.record("alice" if i % 5 else "bob", "shape.upload", f"shape{i}", {"pad": "x" * (i % 7)})
    assert [e["target"] for e in log.read(limit=100)] == [f"shape{i}" for i in range(50)]
    page = log.page(limit=4, offset=2)
    assert page.total == 50 and [e["target"] for e in page.items] == [f"shape{i}" for i in (47, 46, 45, 44)]
    assert log.page(limit=100, user="bob").total == 10


def test_the_audit_log_never_writes_a_token_or_the_data_path(tmp_path):
    users, log = users_of(tmp_path), audit_of(tmp_path)
    token = users.add("alice")
    log.record("alice", "session.fail", "s1", {"error": f"bad token {token} in {tmp_path}/sessions/s1.json"})
    text = repr(database_rows(tmp_path, "SELECT actor, target, detail FROM audit"))
    assert token not in text and str(tmp_path) not in text
    assert log.read()[0]["detail"]["error"] == "bad token cfm_[redacted] in [data]/sessions/s1.json"


@pytest.mark.parametrize("options", [{"limit": 0}, {"limit": "5"}, {"since": "yesterday"}])
def test_bad_audit_queries_are_invalid(tmp_path, options):
    with pytest.raises(CurvefmError) as error:
        audit_of(tmp_path).read(**options)
    assert error.value.code == "invalid"


def test_two_processes_appending_audit_events_lose_none(tmp_path):
    script = """
        from curvefm.access import audit_of
        log = audit_of(data)
        #GO
        for i in range(300):
            log.record(args[0], "job.cancel", str(i), {"filler": args[0] * 4000})
    """
    run_together(tmp_path, script, "a", "b")
    events = audit_of(tmp_path).read(limit=1000)
    assert len(events) == 600
    for user in "ab":
        mine = [e for e in events if e["user"] == user]
        assert [e["target"] for e in mine] == [str(i) for i in range(300)]
        assert all(e["detail"]["filler"] == user * 4000 for e in mine)


def test_a_database_file_that_is_not_curvefms_is_a_clear_error(tmp_path):
    (tmp_path / "curvefm.db").write_bytes(b"this is not a database, " * 100)
    with pytest.raises(CurvefmError) as error:
        users_of(tmp_path).list()
    assert error.value.code == "internal" and "curvefm.db" in error.value.message
