"""The blob store's interface on files, and the meshes no shape row wants (both engines)."""

from __future__ import annotations

import pytest

from curvefm.errors import InvalidInput, NotFound
from curvefm.records.blobs import FileBlobs, unreferenced_meshes
from curvefm.records.shapes import Shapes


def test_file_blobs(tmp_path):
    blobs = FileBlobs(tmp_path)
    assert blobs.put("meshes/abc.npz", b"12345") is True
    assert blobs.put("meshes/abc.npz", b"other") is False  # immutable: a key names the same bytes forever
    assert blobs.get("meshes/abc.npz") == b"12345" and blobs.exists("meshes/abc.npz")
    blobs.put("results/j1/map.npz", b"x" * 10)
    blobs.put("results/j1/quality.json", b"{}")
    assert blobs.size("results/j1") == 12 and blobs.size("meshes/abc.npz") == 5 and blobs.size("results/j2") == 0
    assert list(blobs.keys("results/j1")) == ["results/j1/map.npz", "results/j1/quality.json"]
    (tmp_path / "meshes" / ".abc.npz.123.tmp").write_bytes(b"half")
    assert list(blobs.keys("meshes")) == ["meshes/abc.npz"]
    blobs.delete("results/j1")
    assert not blobs.exists("results/j1/map.npz") and list(blobs.keys("nothing")) == []
    with pytest.raises(NotFound):
        blobs.get("meshes/none.npz")
    for bad in ("", "../etc/passwd", "/abs", "meshes/.hidden", "a//b"):
        with pytest.raises(InvalidInput):
            blobs.put(bad, b"")


def test_unreferenced_meshes(db, tmp_path):
    blobs = FileBlobs(tmp_path)
    for shape in ("kept", "orphan"):
        blobs.put(f"meshes/{shape}.npz", b"mesh")
    Shapes(db).add("kept", 4)
    assert unreferenced_meshes(db, blobs) == ["meshes/orphan.npz"]
