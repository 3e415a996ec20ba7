"""The blob store: immutable, content-addressed files beside the database (meshes, bases, display copies,
results), behind one small interface, so the records never hold a path and another backend (an object store)
could take the files' place.

A key is a relative path of safe parts (``meshes/<hash>.npz``, ``results/<job id>/map.npz``). A blob is written
whole to a temporary name, fsync'ed and renamed into place (:func:`curvefm.store.atomic_write`): a reader sees
nothing or all of it. Blobs are never changed in place; a key names the same bytes forever, or nothing.

The database says which blobs are wanted; :func:`unreferenced_meshes` finds meshes no shape row points at (left
by an upload whose transaction was refused), for a sweep to delete.
"""

from __future__ import annotations

import os
import re
import shutil
from collections.abc import Iterator
from pathlib import Path
from typing import Protocol

from sqlalchemy import select

from curvefm.errors import InvalidInput, NotFound
from curvefm.records import models as m
from curvefm.records.engine import Database
from curvefm.store import atomic_write

_PART = re.compile(r"^[A-Za-z0-9_][A-Za-z0-9_.-]{0,127}$")


class BlobStore(Protocol):
    def put(self, key: str, data: bytes) -> bool:
        """Store ``data`` under ``key`` unless a blob is there already; returns whether it wrote."""

    def get(self, key: str) -> bytes: ...

    def exists(self, key: str) -> bool: ...

    def size(self, key: str) -> int:
        """The blob's bytes, or the sum of the blobs under ``key`` taken as a folder (0: none)."""

    def delete(self, key: str) -> None:
        """Remove the blob, or every blob under ``key`` taken as a folder."""

    def keys(self, prefix: str) -> Iterator[str]:
        """The keys of the blobs directly under the folder ``prefix``, sorted."""


class FileBlobs:
    """Blobs as files under ``root`` (the data directory)."""

    def __init__(self, root: str | os.PathLike[str]):
        self.root = Path(root)

    def path(self, key: str) -> Path:
        parts = key.split("/")
        if not key or not all(_PART.match(part) for part in parts):
            raise InvalidInput(f"bad blob key {key!r}: parts of letters, digits, '_', '.' and '-', none hidden")
        return self.root.joinpath(*parts)

    def put(self, key: str, data: bytes) -> bool:
        path = self.path(key)
        if path.is_file():
            return False
        atomic_write(path, data)
        return True

    def get(self, key: str) -> bytes:
        try:
            return self.path(key).read_bytes()
        except (FileNotFoundError, IsADirectoryError):
            raise NotFound(f"no blob {key}") from None

    def exists(self, key: str) -> bool:
        return self.path(key).is_file()

    def size(self, key: str) -> int:
        path = self.path(key)
        try:
            if path.is_dir():
                return sum(p.stat().st_size for p in path.rglob("*") if p.is_file())
            return path.stat().st_size
        except FileNotFoundError:
            return 0

    def delete(self, key: str) -> None:
        path = self.path(key)
        if path.is_dir():
            shutil.rmtree(path, ignore_errors=True)
        else:
            path.unlink(missing_ok=True)

    def keys(self, prefix: str) -> Iterator[str]:
        folder = self.path(prefix)
        if folder.is_dir():
            for path in sorted(folder.iterdir()):
                if _PART.match(path.name):  # temporary files (".name.tmp") are not blobs
                    yield f"{prefix}/{path.name}"


def unreferenced_meshes(database: Database, blobs: BlobStore) -> list[str]:
    """Keys of mesh blobs (``meshes/<hash>.npz``) that no shape row points at."""
    with database.read() as conn:
        shapes = set(conn.execute(select(m.Shape.hash)).scalars())
    return [key for key in blobs.keys("meshes") if key.endswith(".npz") and key[7:-4] not in shapes]
