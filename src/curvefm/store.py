"""The artifact store: one data directory holding meshes and bases, content-addressed.

Layout under the root (``CURVEFM_DATA``, default ``~/.local/share/curvefm``)::

    meshes/<mesh hash>.npz                         validated mesh arrays
    bases/<mesh hash>/<plugin>-k<k>-<params>.npz   eigenbases
    displays/<mesh hash>/v<vertex count>.npz       display copies of big meshes (curvefm.geometry.display)
    curvefm.db                                     the records' database (curvefm.records), unless
                                                   CURVEFM_DATABASE_URL names another

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
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import BaseModel

from curvefm import registry
from curvefm.errors import NotFound, shown
from curvefm.geometry import DisplayMesh, Mesh, MeshReport, display_mesh
from curvefm.progress import Progress, no_progress
from curvefm.spectral import (
    DEFAULT_BASIS,
    Basis,
    LaplaceBeltramiParams,
    laplace_beltrami_basis,
    laplace_beltrami_storage_params,
)


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


def params_key(params: dict[str, Any]) -> str:
    return hashlib.sha256(json.dumps(params, sort_keys=True).encode()).hexdigest()[:12]


class Store:
    def __init__(self, root: str | os.PathLike[str] | None = None) -> None:
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
            # allow_pickle: numpy's default, named so that mypy matches **arrays to savez's **kwds only
            np.savez(buffer, meta=np.array(json.dumps(meta)), allow_pickle=True, **arrays)
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

    def delete_mesh(self, mesh_hash: str) -> None:
        """Remove the mesh, its bases and its display copies (its record, :class:`curvefm.records.shapes.Shapes`,
        goes first)."""
        if not self.has_mesh(mesh_hash):
            raise NotFound(f"no shape with id '{mesh_hash}'")
        self.delete_bases(mesh_hash)
        if _safe_id(mesh_hash):
            shutil.rmtree(self.root / "displays" / mesh_hash, ignore_errors=True)
        self.mesh_path(mesh_hash).unlink(missing_ok=True)

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

    def find_display(self, mesh: Mesh, vertex_count: int) -> DisplayMesh | None:
        """The stored display copy of ``mesh`` made for ``vertex_count``, if one is stored and fits the mesh."""
        found = self.get_display(mesh.content_hash, vertex_count)
        return found if found is not None and found.n_vertices == mesh.n_vertices else None

    def ensure_display(self, mesh: Mesh, vertex_count: int) -> DisplayMesh:
        """The stored display copy of ``mesh``, or make it (seconds to minutes at scan size) and store it."""
        found = self.find_display(mesh, vertex_count)
        if found is None:
            found = display_mesh(mesh, vertex_count)
            self.put_display(mesh.content_hash, vertex_count, found)
        return found

    def put_display(self, mesh_hash: str, vertex_count: int, display: DisplayMesh) -> None:
        out = io.BytesIO()
        np.savez(
            out,
            vertex_ids=display.vertex_ids,
            faces=display.faces,
            nearest=display.nearest,
            n_vertices=display.n_vertices,
        )
        atomic_write(self.display_path(mesh_hash, vertex_count), out.getvalue())

    # -- bases --------------------------------------------------------------------------------------------
    def basis_path(self, mesh_hash: str, plugin: str, k: int, params: dict[str, Any]) -> Path:
        return self.root / "bases" / mesh_hash / f"{plugin}-k{k}-{params_key(params)}.npz"

    def find_basis(
        self, mesh_hash: str, k: int, plugin: str = DEFAULT_BASIS, params: dict[str, Any] | BaseModel | None = None
    ) -> Basis | None:
        """A stored basis with at least k functions (truncated to k), or None. ``params`` default to the
        plugin's defaults, the form :meth:`ensure_basis` stores under."""
        path = self._basis_file(mesh_hash, k, plugin, _storage_params(plugin, params))
        return None if path is None else Basis.from_bytes(path.read_bytes()).truncated(k)

    def has_basis(
        self, mesh_hash: str, k: int, plugin: str = DEFAULT_BASIS, params: dict[str, Any] | BaseModel | None = None
    ) -> bool:
        """Whether :meth:`find_basis` would find one, without loading it."""
        return self._basis_file(mesh_hash, k, plugin, _storage_params(plugin, params)) is not None

    def _basis_file(self, mesh_hash: str, k: int, plugin: str, canonical: dict[str, Any]) -> Path | None:
        """The smallest stored basis with at least k functions, its parameters as the plugin stores them."""
        folder = self.root / "bases" / mesh_hash
        best = None
        for path in folder.glob(f"{plugin}-k*-{params_key(canonical)}.npz"):
            stored_k = int(path.name[len(plugin) + 2 :].split("-")[0])
            if stored_k >= k and (best is None or stored_k < best[0]):
                best = (stored_k, path)
        return None if best is None else best[1]

    def stored_bases(self, mesh_hash: str) -> list[dict[str, Any]]:
        out = []
        for path in sorted((self.root / "bases" / mesh_hash).glob("*.npz")):
            plugin, rest = path.stem.rsplit("-k", 1)
            k, key = rest.split("-")
            out.append({"plugin": plugin, "k": int(k), "params_key": key})
        return out

    def delete_bases(self, mesh_hash: str) -> list[dict[str, Any]]:
        """Remove every stored basis of the mesh; returns what was removed (as :meth:`stored_bases`)."""
        removed = self.stored_bases(mesh_hash)
        if _safe_id(mesh_hash):
            shutil.rmtree(self.root / "bases" / mesh_hash, ignore_errors=True)
        return removed

    def put_basis(
        self, mesh_hash: str, basis: Basis, plugin: str, params: dict[str, Any] | BaseModel | None = None
    ) -> None:
        """Store a basis computed by ``plugin`` with ``params``, filed as the plugin files them."""
        path = self.basis_path(mesh_hash, plugin, basis.k, _storage_params(plugin, params))
        atomic_write(path, basis.to_bytes())

    def ensure_basis(
        self,
        mesh: Mesh,
        k: int,
        plugin: str = DEFAULT_BASIS,
        params: dict[str, Any] | BaseModel | None = None,
        progress: Progress = no_progress,
    ) -> Basis:
        """The stored basis, or compute it (the default basis in the core, any other with the named basis plugin)
        and store it."""
        compute, parsed, canonical = _basis_computation(plugin, params)
        mesh_hash = self.put_mesh(mesh)
        found = self._basis_file(mesh_hash, k, plugin, canonical)
        if found is not None:
            progress(1.0, "basis found in the store")
            return Basis.from_bytes(found.read_bytes()).truncated(k)
        basis = compute(mesh, k, parsed, progress)
        self.put_basis(mesh_hash, basis, plugin, parsed)
        return basis


def _safe_id(identifier: str) -> bool:
    return isinstance(identifier, str) and identifier.isalnum() and 0 < len(identifier) <= 64


#: ``compute(mesh, k, parsed, progress)``: its parsed parameters are the basis's own model (Any: each takes its own)
_BasisComputation = Callable[[Mesh, int, Any, Progress], Basis]


def _basis_computation(
    plugin: str, params: dict[str, Any] | BaseModel | None
) -> tuple[_BasisComputation, BaseModel, dict[str, Any]]:
    """How the basis named ``plugin`` is computed, ``compute(mesh, k, parsed, progress)``, with its parsed parameters
    and those it is stored under: the default basis straight from :mod:`curvefm.spectral` (the core needs no plugin
    for it), any other from its basis plugin."""
    if plugin == DEFAULT_BASIS:
        default = registry.parse_params(plugin, LaplaceBeltramiParams, params)
        return laplace_beltrami_basis, default, laplace_beltrami_storage_params(default)
    basis_plugin, parsed = registry.load("basis", plugin, params)
    return basis_plugin.run, parsed, basis_plugin.storage_params(parsed)


def _storage_params(plugin: str, params: dict[str, Any] | BaseModel | None) -> dict[str, Any]:
    return _basis_computation(plugin, params)[2]
