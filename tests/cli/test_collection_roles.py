"""``curvefm collection roles``, run as a lab admin runs it on a real data directory: grants and takes away
roles, lists them with the creator first, refuses what the service refuses, and writes the audit log."""

import subprocess
import sys

from support.shapes import ellipsoid, off_bytes

from curvefm.access import audit_of, users_of


def curvefm(*args, data):
    command = [sys.executable, "-m", "curvefm.cli", *map(str, args), "--data", str(data)]
    return subprocess.run(command, capture_output=True, text=True)


def test_roles_are_granted_listed_and_taken_away(tmp_path):
    data, mesh = tmp_path / "data", tmp_path / "template.off"
    mesh.write_bytes(off_bytes(ellipsoid(6, 12)))
    (tmp_path / "curves.json").write_text('{"curves": [{"waypoints": [0, 40]}]}')
    for name in ("tina", "alice", "bob"):
        users_of(data).add(name)
    made = curvefm(
        "collection", "create", mesh, "--curves", tmp_path / "curves.json", "--k", 8, "--owner", "tina", data=data
    )
    assert made.returncode == 0, made.stderr
    collection = made.stdout.split()[1]

    granted = curvefm("collection", "roles", collection, "--grant", "alice", "annotator", data=data)
    assert granted.returncode == 0, granted.stderr
    curvefm("collection", "roles", collection, "--grant", "bob", "viewer", data=data).check_returncode()
    listed = [line.split()[:2] for line in curvefm("collection", "roles", collection, data=data).stdout.splitlines()]
    assert listed == [["tina", "owner"], ["alice", "annotator"], ["bob", "viewer"]]

    revoked = curvefm("collection", "roles", collection, "--revoke", "bob", data=data)
    assert [line.split()[0] for line in revoked.stdout.splitlines()] == ["tina", "alice"]
    again = curvefm("collection", "roles", collection, "--revoke", "bob", data=data)
    assert again.returncode != 0 and "holds no role" in again.stderr
    creator = curvefm("collection", "roles", collection, "--grant", "tina", "viewer", data=data)
    assert creator.returncode != 0 and "owner for good" in creator.stderr
    wrong = curvefm("collection", "roles", collection, "--grant", "alice", "chief", data=data)
    assert wrong.returncode != 0 and "a role is one of" in wrong.stderr

    events = [(e["user"], e["action"], e["detail"]["user"]) for e in audit_of(data).read() if e["target"] == collection]
    assert events == [
        ("cli", "collection.grant", "alice"),
        ("cli", "collection.grant", "bob"),
        ("cli", "collection.revoke", "bob"),
    ]
