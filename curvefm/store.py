"""The artifact store: one data directory holding meshes and bases, content-addressed.

Layout under the root (``CURVEFM_DATA``, default ``~/.local/share/curvefm``)::

    meshes/<mesh hash>.npz                         validated mesh arrays
    meshes/<mesh hash>.uploaders                   who uploaded it (user names, one a line, appended)
    bases/<mesh hash>/<plugin>-k<k>-<params>.npz   eigenbases
    displays/<mesh hash>/v<vertex count>.npz       display copies of big meshes (curvefm.geometry.display)
    sessions/<session id>.json                     session records (curvefm.session.SessionStore)

Every write goes to a temporary file that is fsync'ed and renamed into place, so readers (other processes,
other machines on a shared volume) see either nothing or a whole file, and a crash never leaves half a file.
"""

from __future__ import annotations

import hashlib
import io
import json
import os
import shutil
import tempfile
from pathlib import Path

import numpy as np
from pydantic import BaseModel

from curvefm import registry
from curvefm.errors import NotFound, shown
from curvefm.geometry import DisplayMesh, Mesh, MeshReport
from curvefm.progress import Progress, no_progress
from curvefm.spectral import Basis


def default_data_dir() -> Path:
    return Path(os.environ.get("CURVEFM_DATA") or Path.home() / ".local" / "share" / "curvefm")


def atomic_write(path: Path, data: bytes) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    dir_fd = os.open(path.parent, os.O_DIRECTORY)
    try:
        os.fsync(dir_fd)
    finally:
        os.close(dir_fd)


def params_key(params: dict) -> str:
    return hashlib.sha256(json.dumps(params, sort_keys=True).encode()).hexdigest()[:12]


class Store:
    def __init__(self, root: str | os.PathLike | None = None):
        self.root = Path(root) if root is not None else default_data_dir()
        self.root.mkdir(parents=True, exist_ok=True)

    # -- meshes -------------------------------------------------------------------------------------------
    def mesh_path(self, mesh_hash: str) -> Path:
        return self.root / "meshes" / f"{mesh_hash}.npz"

    def put_mesh(self, mesh: Mesh) -> str:
        path = self.mesh_path(mesh.content_hash)
        if not path.exists():
            buffer = io.BytesIO()
            arrays = dict(vertices=mesh.vertices, faces=mesh.faces, file_ids=mesh.file_ids)
            if mesh.uv is not None:
                arrays["uv"] = mesh.uv
            meta = dict(
                name=mesh.name,
                n_file_vertices=mesh.n_file_vertices,
                report=mesh.report.as_dict(),
                texture_path=mesh.texture_path,
            )
            np.savez(buffer, meta=np.array(json.dumps(meta)), **arrays)
            atomic_write(path, buffer.getvalue())
        return mesh.content_hash

    def has_mesh(self, mesh_hash: str) -> bool:
        return _safe_id(mesh_hash) and self.mesh_path(mesh_hash).is_file()

    def get_mesh(self, mesh_hash: str) -> Mesh:
        if not self.has_mesh(mesh_hash):
            raise NotFound(f"no shape with id '{shown(mesh_hash)}'")
        with np.load(self.mesh_path(mesh_hash)) as z:
            meta = json.loads(str(z["meta"]))
            return Mesh(
                vertices=z["vertices"],
                faces=z["faces"],
                file_ids=z["file_ids"],
                n_file_vertices=meta["n_file_vertices"],
                report=MeshReport(**meta["report"]),
                uv=z["uv"] if "uv" in z else None,
                texture_path=meta["texture_path"],
                name=meta["name"],
            )

    def mesh_ids(self) -> list[str]:
        return sorted(p.stem for p in (self.root / "meshes").glob("*.npz"))

    def add_uploader(self, mesh_hash: str, user: str) -> bool:
        """Note that ``user`` uploaded the mesh (an appended line, so writers never interleave); False when they
        had already."""
        if user in self.uploaders(mesh_hash):
            return False
        fd = os.open(self._uploaders_path(mesh_hash), os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
        try:
            os.write(fd, f"{user}\n".encode())
        finally:
            os.close(fd)
        return True

    def uploaders(self, mesh_hash: str) -> list[str]:
        """Who uploaded the mesh, first uploader first (empty for meshes stored before uploaders were kept)."""
        try:
            names = self._uploaders_path(mesh_hash).read_text().split()
        except FileNotFoundError:
            return []
        return list(dict.fromkeys(names))

    def delete_mesh(self, mesh_hash: str) -> None:
        """Remove the mesh, its uploaders, its bases and its display copies."""
        if not self.has_mesh(mesh_hash):
            raise NotFound(f"no shape with id '{mesh_hash}'")
        self.delete_bases(mesh_hash)
        if _safe_id(mesh_hash):
            shutil.rmtree(self.root / "displays" / mesh_hash, ignore_errors=True)
        self.mesh_path(mesh_hash).unlink(missing_ok=True)
        self._uploaders_path(mesh_hash).unlink(missing_ok=True)

    def _uploaders_path(self, mesh_hash: str) -> Path:
        return self.root / "meshes" / f"{mesh_hash}.uploaders"

    # -- display copies -----------------------------------------------------------------------------------
    def display_path(self, mesh_hash: str, vertex_count: int) -> Path:
        return self.root / "displays" / mesh_hash / f"v{int(vertex_count)}.npz"

    def get_display(self, mesh_hash: str, vertex_count: int) -> DisplayMesh | None:
        """The stored display copy made for ``vertex_count``, or None (none stored, or not readable: made again)."""
        try:
            with np.load(io.BytesIO(self.display_path(mesh_hash, vertex_count).read_bytes())) as arrays:
                return DisplayMesh(arrays["vertex_ids"], arrays["faces"], arrays["nearest"], int(arrays["n_vertices"]))
        except (OSError, ValueError, KeyError, EOFError):
            return None

    def put_display(self, mesh_hash: str, vertex_count: int, display: DisplayMesh) -> None:
        out = io.BytesIO()
        np.savez(out, vertex_ids=display.vertex_ids, faces=display.faces, nearest=display.nearest,
                 n_vertices=display.n_vertices)  # fmt: skip
        atomic_write(self.display_path(mesh_hash, vertex_count), out.getvalue())

    # -- bases --------------------------------------------------------------------------------------------
    def basis_path(self, mesh_hash: str, plugin: str, k: int, params: dict) -> Path:
        return self.root / "bases" / mesh_hash / f"{plugin}-k{k}-{params_key(params)}.npz"

    def find_basis(
        self, mesh_hash: str, k: int, plugin: str = "laplace-beltrami", params: dict | BaseModel | None = None
    ):
        """A stored basis with at least k functions (truncated to k), or None. ``params`` default to the
        plugin's defaults, the form :meth:`ensure_basis` stores under."""
        path = self._basis_file(mesh_hash, k, plugin, _storage_params(plugin, params))
        return None if path is None else Basis.from_bytes(path.read_bytes()).truncated(k)

    def has_basis(
        self, mesh_hash: str, k: int, plugin: str = "laplace-beltrami", params: dict | BaseModel | None = None
    ) -> bool:
        """Whether :meth:`find_basis` would find one, without loading it."""
        return self._basis_file(mesh_hash, k, plugin, _storage_params(plugin, params)) is not None

    def _basis_file(self, mesh_hash: str, k: int, plugin: str, canonical: dict) -> Path | None:
        """The smallest stored basis with at least k functions, its parameters as the plugin stores them."""
        folder = self.root / "bases" / mesh_hash
        best = None
        for path in folder.glob(f"{plugin}-k*-{params_key(canonical)}.npz"):
            stored_k = int(path.name[len(plugin) + 2 :].split("-")[0])
            if stored_k >= k and (best is None or stored_k < best[0]):
                best = (stored_k, path)
        return None if best is None else best[1]

    def stored_bases(self, mesh_hash: str) -> list[dict]:
        out = []
        for path in sorted((self.root / "bases" / mesh_hash).glob("*.npz")):
            plugin, rest = path.stem.rsplit("-k", 1)
            k, key = rest.split("-")
            out.append({"plugin": plugin, "k": int(k), "params_key": key})
        return out

    def delete_bases(self, mesh_hash: str) -> list[dict]:
        """Remove every stored basis of the mesh; returns what was removed (as :meth:`stored_bases`)."""
        removed = self.stored_bases(mesh_hash)
        if _safe_id(mesh_hash):
            shutil.rmtree(self.root / "bases" / mesh_hash, ignore_errors=True)
        return removed

    def put_basis(self, mesh_hash: str, basis: Basis, plugin: str, params: dict | BaseModel | None = None) -> None:
        """Store a basis computed by ``plugin`` with ``params``, filed as the plugin files them."""
        path = self.basis_path(mesh_hash, plugin, basis.k, _storage_params(plugin, params))
        atomic_write(path, basis.to_bytes())

    def ensure_basis(
        self,
        mesh: Mesh,
        k: int,
        plugin: str = "laplace-beltrami",
        params: dict | BaseModel | None = None,
        progress: Progress = no_progress,
    ) -> Basis:
        """The stored basis, or compute it with the named basis plugin and store it."""
        basis_plugin, parsed = registry.load("basis", plugin, params)
        canonical = basis_plugin.storage_params(parsed)
        mesh_hash = self.put_mesh(mesh)
        found = self._basis_file(mesh_hash, k, plugin, canonical)
        if found is not None:
            progress(1.0, "basis found in the store")
            return Basis.from_bytes(found.read_bytes()).truncated(k)
        basis = basis_plugin.run(mesh, k, parsed, progress)
        self.put_basis(mesh_hash, basis, plugin, parsed)
        return basis


def _safe_id(identifier: str) -> bool:
    return isinstance(identifier, str) and identifier.isalnum() and 0 < len(identifier) <= 64


def _storage_params(plugin: str, params: dict | BaseModel | None) -> dict:
    basis_plugin, parsed = registry.load("basis", plugin, params)
    return basis_plugin.storage_params(parsed)
