"""``curvefm users``, run as a lab admin runs it: real processes on a real data directory."""

import contextlib
import json
import os
import sqlite3
import subprocess
import sys

from curvefm.access import audit_of, users_of


def users(*args, data=None, env=None):
    data_option = ["--data", str(data)] if data is not None else []
    return subprocess.run(
        [sys.executable, "-m", "curvefm.cli", "users", *map(str, args), *data_option],
        capture_output=True,
        text=True,
        env=env,
    )


def last_word(run) -> str:
    assert run.returncode == 0, run.stderr
    return run.stdout.splitlines()[-1].split()[-1]


def test_add_list_rotate_remove(tmp_path):
    alice = last_word(users("add", "alice", data=tmp_path))
    bob = last_word(users("add", "bob", "--admin", data=tmp_path))
    store = users_of(tmp_path)
    assert store.authenticate(alice).name == "alice" and store.authenticate(bob).admin

    listed = users("list", data=tmp_path)
    assert [line.split()[:2] for line in listed.stdout.splitlines()] == [["alice", "user"], ["bob", "admin"]]
    as_json = json.loads(users("list", "--json", data=tmp_path).stdout)
    assert [(u["name"], u["admin"]) for u in as_json] == [("alice", False), ("bob", True)]

    rotated = last_word(users("token", "alice", "--rotate", data=tmp_path))
    assert store.authenticate(alice) is None and store.authenticate(rotated).name == "alice"

    removed = users("remove", "bob", data=tmp_path)
    assert removed.returncode == 0 and store.authenticate(bob) is None
    assert [u.name for u in store.list()] == ["alice"]

    events = audit_of(tmp_path).read()
    assert [(e["user"], e["action"], e["target"]) for e in events] == [
        ("cli", "user.add", "alice"),
        ("cli", "user.add", "bob"),
        ("cli", "user.rotate", "alice"),
        ("cli", "user.remove", "bob"),
    ]
    with contextlib.closing(sqlite3.connect(tmp_path / "curvefm.db")) as conn:
        audit_text = repr(conn.execute("SELECT * FROM audit").fetchall())
    assert not any(token in audit_text for token in (alice, bob, rotated)) and str(tmp_path) not in audit_text


def test_add_prints_the_login_url_and_the_data_directory(tmp_path):
    added = users("add", "alice", "--url", "https://lab.example:8443/", data=tmp_path)
    token = last_word(added)
    assert f"login URL: https://lab.example:8443/?token={token}" in added.stdout
    assert f"to the data directory {tmp_path.resolve()};" in added.stdout and added.stderr == ""
    assert "login URL: http://127.0.0.1:8000/?token=" in users("add", "bob", data=tmp_path).stdout


def test_add_without_a_data_directory_warns_where_it_wrote(tmp_path):
    home = tmp_path / "home"
    env = {key: value for key, value in os.environ.items() if key != "CURVEFM_DATA"} | {"HOME": str(home)}
    added = users("add", "alice", env=env)
    default = (home / ".local" / "share" / "curvefm").resolve()
    assert added.returncode == 0 and f"to the data directory {default};" in added.stdout
    assert "warning: neither --data nor $CURVEFM_DATA is set" in added.stderr and str(default) in added.stderr
    assert users_of(default).authenticate(last_word(added)).name == "alice"
    quiet = users("add", "bob", env=env | {"CURVEFM_DATA": str(tmp_path / "data")})
    assert quiet.returncode == 0 and quiet.stderr == ""


def test_errors_exit_2_and_say_what_was_wrong(tmp_path):
    users("add", "alice", data=tmp_path)
    cases = [
        (("add", "alice"), "user 'alice' already exists"),
        (("add", "al ice"), "bad user name 'al ice'"),
        (("remove", "bob"), "no user 'bob'"),
        (("token", "bob", "--rotate"), "no user 'bob'"),
        (("token", "alice"), "cannot be shown again; 'curvefm users token NAME --rotate'"),
    ]
    for args, message in cases:
        run = users(*args, data=tmp_path)
        assert run.returncode == 2 and run.stderr.startswith("curvefm: error: ") and message in run.stderr, args
        assert "cfm_" not in run.stdout + run.stderr
    assert [u.name for u in users_of(tmp_path).list()] == ["alice"]


def test_the_data_directory_defaults_to_curvefm_data(tmp_path):
    env = {**os.environ, "CURVEFM_DATA": str(tmp_path)}
    token = last_word(users("add", "carol", env=env))
    assert users_of(tmp_path).authenticate(token).name == "carol"
    assert "no users" in users("list", data=tmp_path / "empty").stdout
