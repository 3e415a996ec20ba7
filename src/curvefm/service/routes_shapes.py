"""``/shapes``: upload, list and fetch meshes; request and delete bases; delete shapes. Shapes are a library
every user sees; the uploaders (and admins) may delete them."""

from __future__ import annotations

import gzip
import json
import os
import re
import shutil
import tempfile
from pathlib import Path
from typing import Annotated, Literal

import numpy as np
from fastapi import APIRouter, File, Form, Query, Request, Response, UploadFile

from curvefm.access import User
from curvefm.cache import LRU
from curvefm.errors import InvalidInput, shown
from curvefm.geometry import SUPPORTED_FORMATS, DisplayMesh, Mesh, load_mesh, texture_coordinates
from curvefm.records.common import MAX_OFFSET, MAX_PAGE
from curvefm.service.auth import AUTHENTICATED, CurrentUser
from curvefm.service.deps import (
    JOB_ERRORS,
    Services,
    ServicesDep,
    job_admission,
    job_model,
    stored_mesh_bytes,
    submit_basis,
    viewer,
)
from curvefm.service.errors import error_responses, require_plugin
from curvefm.service.models import BasisInfo, BasisRequest, JobInfoModel, PointsRequest, ShapeInfo
from curvefm.service.openapi import SchemaRoute
from curvefm.service.owned import LIMIT_HELP, OFFSET_HELP, TOTAL_HEADER, TOTAL_SCHEMA, paged
from curvefm.service.permissions import check_shape_manager, check_unused
from curvefm.service.quotas import stored_bytes
from curvefm.spectral import check_k

router = APIRouter(
    tags=["shapes"], route_class=SchemaRoute, dependencies=AUTHENTICATED, responses=error_responses(401, 403, 507)
)
ERRORS = error_responses(400, 404, 409, 413, 422)
QUOTA_ERRORS = error_responses(400, 404, 409, 413, 422, 429)
UPLOAD_ERRORS = error_responses(
    400,
    413,
    422,
    429,
    described={
        400: "not a mesh curvefm reads (the detail says why)",
        429: "more requests than CURVEFM_RATE_LIMIT, or more big uploads being read at once than "
        "CURVEFM_MAX_CONCURRENT_UPLOADS (Retry-After says when to try again)",
    },
)
COPY_CHUNK = 1 << 20
BINARY = {"type": "string", "format": "binary"}
MESH_FORMAT = "curvefm-mesh-1"
POINTS_FORMAT = "curvefm-points-1"
GZIPPED_MESHES: LRU[bytes] = LRU(16)
"""Binary mesh payloads gzipped once (level 1: about half the bytes, 27 ms for 28k vertices), by shape id and
display copy: a shape's id is its content's hash, so an entry never goes stale."""


MAX_NAME_CHARS = 200
"""A shape's display name (every list of shapes carries it)."""


@router.post(
    "/shapes", status_code=201, response_model=ShapeInfo, responses={200: {"model": ShapeInfo}, **UPLOAD_ERRORS}
)
def upload_shape(
    response: Response,
    file: Annotated[UploadFile, File(description=f"a mesh file: {', '.join(SUPPORTED_FORMATS)}")],
    services: ServicesDep,
    user: CurrentUser,
    name: Annotated[
        str | None,
        Form(max_length=MAX_NAME_CHARS, description="display name (default: the file name without suffix, cut short)"),
    ] = None,
) -> ShapeInfo:
    """Validate and store a mesh. Its id is the content hash, so uploading the same mesh again returns the
    existing shape (200 instead of 201), with you added to its uploaders. A rejected upload stores nothing. A new
    shape counts towards its first uploader's byte quota (413 when over it)."""
    mesh_id, created = store_upload(services, user, file, name)
    response.status_code = 201 if created else 200
    return shape_info(services, mesh_id)


def store_upload(services: Services, user: User, file: UploadFile, name: str | None = None) -> tuple[str, bool]:
    """Validate and store an uploaded mesh of ``user``; returns its id and whether it is new."""
    filename = file.filename or ""
    suffix = Path(filename).suffix.lower()
    if suffix not in SUPPORTED_FORMATS:
        raise InvalidInput(
            f"unsupported mesh format '{shown(suffix) or '(no suffix)'}' of '{shown(filename)}'; supported: "
            f"{', '.join(SUPPORTED_FORMATS)}"
        )
    with services.uploads.admit(_size(file)):  # parsing a big one takes a few times its size in memory
        mesh = _parsed(file, filename, name)
        created = not services.store.has_mesh(mesh.content_hash)
        if created:  # checked and recorded in one transaction: a refused upload stores nothing
            with services.quotas.admit(user, "shapes", stored_bytes(mesh)) as conn:
                services.store.put_mesh(mesh)
                size = stored_mesh_bytes(services.store, mesh.content_hash) or 0
                new_uploader = services.shapes.add(mesh.content_hash, size, user.id, conn, name=mesh.name)
        else:
            size = stored_mesh_bytes(services.store, mesh.content_hash) or 0
            new_uploader = services.shapes.add(mesh.content_hash, size, user.id)  # (named as first uploaded)
    if new_uploader:
        services.audit.record(user.name, "shape.upload", mesh.content_hash)
    return mesh.content_hash, created


@router.get(
    "/shapes",
    response_model=list[ShapeInfo],
    responses={200: {"headers": {TOTAL_HEADER: TOTAL_SCHEMA}}, **error_responses(422)},
)
def list_shapes(
    response: Response,
    services: ServicesDep,
    limit: Annotated[int | None, Query(ge=1, le=MAX_PAGE, description=LIMIT_HELP)] = None,
    offset: Annotated[int, Query(ge=0, le=MAX_OFFSET, description=OFFSET_HELP)] = 0,
) -> list[ShapeInfo]:
    """The stored shapes (every user may see them all) by name, then upload time (the newest first): ``limit`` of
    them from ``offset`` (without ``limit``: all from ``offset``, after recording any mesh the command line stored
    without a record). The ``X-Total-Count`` header says how many there are in all. Counted and sliced by the
    database."""
    if limit is None:
        for mesh_id in set(services.store.mesh_ids()) - set(services.shapes.ids()):
            register_shape(services, mesh_id)
    services.shapes.name_unnamed(lambda shape: _stored_name(services, shape))
    ids, total = paged(lambda n, at: services.shapes.page(limit=n, offset=at), limit, offset)
    response.headers[TOTAL_HEADER] = str(total)
    return [shape_info(services, mesh_id) for mesh_id in ids]


@router.get("/shapes/{shape_id}", response_model=ShapeInfo, responses=ERRORS)
def get_shape(shape_id: str, services: ServicesDep) -> ShapeInfo:
    return shape_info(services, shape_id)


@router.get(
    "/shapes/{shape_id}/mesh",
    responses={200: {"content": {"application/octet-stream": {}, "application/json": {}}}, **ERRORS},
)
def get_shape_mesh(
    shape_id: str,
    request: Request,
    services: ServicesDep,
    format: Literal["binary", "json"] = "binary",
    resolution: Annotated[
        Literal["display", "full"],
        Query(description="display: a big shape's display copy (the default); full: the whole mesh"),
    ] = "display",
) -> Response:
    """The mesh for drawing: for a shape of more than ``CURVEFM_DISPLAY_VERTICES`` vertices (default 50,000) its
    *display copy*, a coarser mesh of about that many vertices that are all vertices of the shape; else (or with
    ``resolution=full``) the whole mesh in internal vertex order.

    ``binary`` (default): a little-endian uint32 ``H``, then ``H`` bytes of JSON header (space-padded to a
    multiple of 4), then the arrays back to back. The header's ``arrays`` gives each array's ``dtype``
    (``float32`` or ``uint32``), ``shape`` and byte ``offset`` counted from the end of the header, so
    ``new Float32Array(buffer, 4 + H + offset, n * 3)`` reads the vertices; ``display_copy`` says whether this
    is a display copy and ``shape_vertices`` how many vertices the shape has. Arrays, one row per vertex drawn:
    ``vertices`` (n x 3), ``faces`` (f x 3, rows of these arrays), ``file_ids`` (n: file id of each vertex),
    ``texcoords`` (n x 2: the texture coordinates the ``uv`` transfer carries, the file's own or generated
    cylindrical ones), ``uv`` (n x 2) if the file had them, and for a display copy only ``vertex_ids`` (n: the
    internal id of each vertex; without it, row i is internal vertex i). The rows of ``GET
    /sessions/{id}/transfer?resolution=display`` and ``.../quality?resolution=display`` are these rows.
    ``json``: the same header fields and arrays as nested lists.

    The binary form is sent gzipped (``Content-Encoding: gzip``, about half the bytes) to a client that accepts it.
    """
    mesh = services.live.mesh(shape_id)
    shown = services.live.display(shape_id) if resolution == "display" else None
    header = {"format": MESH_FORMAT, "name": mesh.name, "display_copy": shown is not None}
    header["shape_vertices"] = mesh.n_vertices
    if format == "json":
        arrays = {name: array.tolist() for name, array in _mesh_arrays(mesh, shown).items()}
        return Response(json.dumps({**header, **arrays}), media_type="application/json")
    if "gzip" not in request.headers.get("accept-encoding", ""):
        body = encode_arrays(header, _mesh_arrays(mesh, shown))
        return Response(body, media_type="application/octet-stream", headers={"Vary": "Accept-Encoding"})
    key = (shape_id, shown.key if shown else None)
    body = GZIPPED_MESHES.get(
        key, lambda: gzip.compress(encode_arrays(header, _mesh_arrays(mesh, shown)), compresslevel=1, mtime=0)
    )
    headers = {"Content-Encoding": "gzip", "Vary": "Accept-Encoding"}
    return Response(body, media_type="application/octet-stream", headers=headers)


@router.post(
    "/shapes/{shape_id}/points",
    response_class=Response,
    responses={200: {"content": {"application/octet-stream": {"schema": BINARY}}}, **ERRORS},
)
def get_points(shape_id: str, body: PointsRequest, services: ServicesDep) -> Response:
    """Where some vertices of the shape are (file ids; a POST, as a path's ids overflow a URL), for drawing what
    names vertices a display copy does not draw: curve paths, the weakest vertex, a pointwise map's images.
    Answered in the binary layout of ``GET /shapes/{id}/mesh`` with the arrays ``positions`` (n x 3 float32, in
    the order asked) and ``nearest_row`` (n uint32: the row of the mesh payload's vertex nearest to each, which for
    a shape drawn whole is the vertex itself). 409 names an id the shape does not have."""
    mesh = services.live.mesh(shape_id)
    ids = mesh.internal_ids(body.vertices, "vertex")
    shown = services.live.display(shape_id)
    arrays = {
        "positions": mesh.vertices[ids].astype("<f4"),
        "nearest_row": (ids if shown is None else shown.nearest[ids]).astype("<u4"),
    }
    return Response(encode_arrays({"format": POINTS_FORMAT}, arrays), media_type="application/octet-stream")


@router.post(
    "/shapes/{shape_id}/bases",
    status_code=202,
    response_model=JobInfoModel,
    responses={**QUOTA_ERRORS, **JOB_ERRORS},
)
def request_basis(shape_id: str, body: BasisRequest, services: ServicesDep, user: CurrentUser) -> JobInfoModel:
    """Queue the basis computation. While the same request (shape, plugin, k, parameters) is queued or
    running, the same job is returned; if the basis already exists, the job finishes at once. 429 at the
    user's concurrent-jobs quota; 413 ``too_large`` when the memory the job states (from the shape's vertices and
    k) is more than any worker's budget (``CURVEFM_WORKER_MEMORY``)."""
    mesh = services.live.mesh(shape_id)
    canonical = require_plugin("basis", body.plugin).parse_params(body.params).model_dump()
    check_k(body.k, mesh.n_vertices, mesh.name or shape_id)
    services.sessions.limits.check("max_k", body.k, f"k = {body.k} basis functions")
    admit = job_admission(services, user)
    info = submit_basis(services, shape_id, body.k, body.plugin, canonical, user.name, admit)
    return job_model(info)


@router.delete("/shapes/{shape_id}", status_code=204, responses=ERRORS)
def delete_shape(shape_id: str, services: ServicesDep, user: CurrentUser) -> Response:
    """Delete a shape with its bases (an uploader or an admin); 409 while a session uses it, naming them. The
    record goes first (refused while anything uses it), then the files."""
    check_shape_manager(services, user, shape_id, "delete it")
    check_unused(services, user, shape_id, "delete it")
    register_shape(services, shape_id)
    services.shapes.delete(shape_id, viewer(user))
    services.store.delete_mesh(shape_id)
    services.audit.record(user.name, "shape.delete", shape_id)
    return Response(status_code=204)


@router.delete("/shapes/{shape_id}/bases", response_model=ShapeInfo, responses=ERRORS)
def delete_bases(shape_id: str, services: ServicesDep, user: CurrentUser) -> ShapeInfo:
    """Delete every stored basis of a shape (an uploader or an admin), e.g. to free disk; 409 while a session
    uses the shape (its solver is rebuilt from them). Requesting a basis computes it again."""
    check_shape_manager(services, user, shape_id, "delete its bases")
    check_unused(services, user, shape_id, "delete its bases")
    removed = services.store.delete_bases(shape_id)
    services.audit.record(user.name, "shape.bases.delete", shape_id, {"bases": len(removed)})
    return shape_info(services, shape_id)


def shape_info(services: Services, shape_id: str) -> ShapeInfo:
    mesh = services.live.mesh(shape_id)
    return ShapeInfo(
        id=shape_id,
        name=mesh.name,
        n_vertices=mesh.n_vertices,
        n_faces=len(mesh.faces),
        n_file_vertices=mesh.n_file_vertices,
        has_uv=mesh.uv is not None,
        uploaders=services.shapes.uploaders(shape_id),
        report=mesh.report.as_dict(),
        bases=[BasisInfo(**b) for b in services.store.stored_bases(shape_id)],
        uploaded_at=services.shapes.uploaded_at(shape_id),
    )


def register_shape(services: Services, shape_id: str) -> None:
    """Record a stored mesh that has no record yet (stored by the command line), charged to nobody."""
    size = stored_mesh_bytes(services.store, shape_id)
    if size is not None:
        services.shapes.add(shape_id, size, name=_stored_name(services, shape_id) or "")


def _stored_name(services: Services, shape_id: str) -> str | None:
    """The name stored with the mesh (None: its blob is gone)."""
    if not services.store.has_mesh(shape_id):
        return None
    return services.live.mesh(shape_id).name or shape_id[:12]


def encode_arrays(header: dict, arrays: dict[str, np.ndarray]) -> bytes:
    """The binary layout of ``GET /shapes/{id}/mesh``: the header with each array's place, then the arrays."""
    layout, offset = {}, 0
    for name, array in arrays.items():
        layout[name] = {"dtype": array.dtype.name, "shape": list(array.shape), "offset": offset}
        offset += array.nbytes
    encoded = json.dumps({**header, "arrays": layout}).encode()
    encoded += b" " * (-len(encoded) % 4)
    parts = [np.uint32(len(encoded)).astype("<u4").tobytes(), encoded]
    return b"".join(parts + [array.tobytes() for array in arrays.values()])


def _mesh_arrays(mesh: Mesh, shown: DisplayMesh | None) -> dict[str, np.ndarray]:
    """The per-vertex arrays of the whole mesh, or of its display copy ``shown`` (rows at its vertex ids)."""
    rows = slice(None) if shown is None else shown.vertex_ids
    arrays = {
        "vertices": mesh.vertices[rows].astype("<f4"),
        "faces": (mesh.faces if shown is None else shown.faces).astype("<u4"),
        "file_ids": mesh.file_ids[rows].astype("<u4"),
        "texcoords": texture_coordinates(mesh)[rows].astype("<f4"),
    }
    if mesh.uv is not None:
        arrays["uv"] = mesh.uv[rows].astype("<f4")
    if shown is not None:
        arrays["vertex_ids"] = shown.vertex_ids.astype("<u4")
    return arrays


def _size(file: UploadFile) -> int:
    if file.size is not None:
        return file.size
    return file.file.seek(0, os.SEEK_END)  # (the copy seeks back to the start)


def _parsed(file: UploadFile, filename: str, name: str | None) -> Mesh:
    with tempfile.TemporaryDirectory(prefix="curvefm-upload-") as folder:
        path = Path(folder) / _safe_filename(filename)  # messages then name the user's file
        file.file.seek(0)
        with open(path, "wb") as out:  # the body limit (BodySizeLimit) has bounded the upload already
            shutil.copyfileobj(file.file, out, COPY_CHUNK)
        return load_mesh(path, name=name or Path(filename).stem[:MAX_NAME_CHARS])


def _safe_filename(filename: str) -> str:
    """The upload's file name as a temporary file may have it: safe characters, and short enough for any file
    system (255 bytes), keeping its suffix."""
    path = Path(filename)
    stem = re.sub(r"[^A-Za-z0-9._-]", "_", path.stem).lstrip(".")[:MAX_NAME_CHARS] or "upload"
    return stem + re.sub(r"[^A-Za-z0-9.]", "_", path.suffix)[:16]
