"""Corresponding landmark configurations of a session's two shapes.

Each curve pair gives two fixed landmarks (its endpoints) and ``semilandmarks`` points between them, placed at equal
arc-length fractions of the traced vertex path on each shape (so the i-th semilandmark of the source curve answers
the i-th of the target curve); pseudo-landmarks are vertices of the source spread by farthest-point sampling, each
with the target vertex the session's pointwise map gives it. The order, the same on both shapes: every curve's
endpoints (start, end; curve by curve), then every curve's semilandmarks, then the pseudo-landmarks.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from curvefm.errors import InvalidInput
from curvefm.geometry import Mesh, farthest_point_sampling
from curvefm.pointwise import pointwise_from_both
from curvefm.session import SessionRecord

if TYPE_CHECKING:
    from curvefm.session import SessionEditor
    from curvefm.spectral import Basis

DEFAULT_SEMILANDMARKS = 20
MAX_SEMILANDMARKS = 1000
MAX_PSEUDO_LANDMARKS = 10_000


@dataclass(frozen=True)
class CurveLandmarks:
    """Where one curve's landmarks are in the configuration (0-based indices)."""

    label: str
    start: int
    end: int
    sliders: range

    @property
    def control_points(self) -> list[int]:
        """The curve from start to end: its endpoints with its semilandmarks between them."""
        return [self.start, *self.sliders, self.end]


@dataclass(frozen=True)
class Configuration:
    """The same landmarks on several shapes (specimens): a session's are ``points[0]`` on the source and
    ``points[1]`` on the target, a collection's one per member; ``(L, 3)`` in each mesh's own coordinates.
    ``labels`` name them, ``curves`` and ``pseudo`` say which are which; ``pseudo_vertices``, when known, the
    vertex (file id) of each pseudo-landmark on each specimen, and ``pseudo_origin`` the vertex of the template
    (a session's source) it was chosen at."""

    names: tuple[str, ...]
    points: tuple[np.ndarray, ...]
    labels: list[str]
    curves: list[CurveLandmarks]
    pseudo: range
    revision: int
    pseudo_vertices: tuple[np.ndarray, ...] = ()
    pseudo_origin: np.ndarray = field(default_factory=lambda: np.empty(0, dtype=np.int64))

    @property
    def size(self) -> int:
        return len(self.labels)


def resample_path(mesh: Mesh, path: np.ndarray, count: int) -> np.ndarray:
    """``count`` points (``(count, 3)``, both ends included) at equal arc-length steps along the vertex path
    ``path`` (internal ids): on the mesh's edges, hence on its surface."""
    positions = mesh.vertices[path]
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(positions, axis=0), axis=1))])
    at = np.linspace(0.0, arc[-1], count)
    return np.column_stack([np.interp(at, arc, positions[:, axis]) for axis in range(3)])


def pseudo_landmarks(
    mesh_M: Mesh, basis_M: Basis, basis_N: Basis, C_MN: np.ndarray, C_NM: np.ndarray, count: int
) -> tuple[np.ndarray, np.ndarray]:
    """``count`` source vertices by farthest-point sampling and the target vertex each maps to (internal ids), by
    the nearest neighbours of both functional maps (:func:`curvefm.pointwise.pointwise_from_both`, M -> N)."""
    on_M = farthest_point_sampling(mesh_M, count)
    on_N = pointwise_from_both(C_NM, C_MN, basis_N, basis_M, rows=on_M)
    return on_M, np.asarray(on_N, dtype=np.int64)


def session_configuration(
    record: SessionRecord,
    meshes: tuple[Mesh, Mesh],
    semilandmarks: int = DEFAULT_SEMILANDMARKS,
    pseudo: tuple[np.ndarray, np.ndarray] | None = None,
) -> Configuration:
    """The configuration of ``record``'s curves (``semilandmarks`` per curve) and of the ``pseudo`` vertex pairs
    (internal ids on source and target)."""
    check_counts(semilandmarks, 0 if pseudo is None else len(pseudo[0]))
    if not record.curves and pseudo is None:
        raise InvalidInput(f"session {record.id} has no curves: nothing to export (ask for pseudo-landmarks)")
    n_curves = len(record.curves)
    sides: list[list[np.ndarray]] = [[], []]
    for side, (mesh, paths) in enumerate(zip(meshes, _paths(record), strict=True)):
        resampled = [resample_path(mesh, mesh.internal_ids(p, "path vertex"), semilandmarks + 2) for p in paths]
        sides[side] = [np.array([end for r in resampled for end in (r[0], r[-1])]).reshape(-1, 3)]
        sides[side] += [r[1:-1] for r in resampled]
        if pseudo is not None:
            sides[side].append(mesh.vertices[pseudo[side]])
    curves, labels = _curve_layout(record, semilandmarks)
    n_pseudo = 0 if pseudo is None else len(pseudo[0])
    first_pseudo = 2 * n_curves + n_curves * semilandmarks
    labels += [f"p{i + 1}" for i in range(n_pseudo)]
    points = (np.concatenate(sides[0]), np.concatenate(sides[1]))
    names = (meshes[0].name or record.source, meshes[1].name or record.target)
    return Configuration(names, points, labels, curves, range(first_pseudo, first_pseudo + n_pseudo), record.revision)


def live_configuration(
    editor: SessionEditor, session_id: str, semilandmarks: int = DEFAULT_SEMILANDMARKS, pseudo: int = 0
) -> Configuration:
    """The configuration of a session as it is now, its pseudo-landmarks carried by its live maps."""
    check_counts(semilandmarks, pseudo)
    with editor.live.using(session_id) as live:
        live.solver.settle()
        record, pair, solver = live.record, live.pair, live.solver
        C_MN, C_NM = solver.C_MN, solver.C_NM
    meshes = (pair.mesh_M, pair.mesh_N)
    _check_pseudo(pseudo, pair.mesh_M)
    pairs = pseudo_landmarks(pair.mesh_M, solver.basis_M, solver.basis_N, C_MN, C_NM, pseudo) if pseudo else None
    return session_configuration(record, meshes, semilandmarks, pairs)


def refined_configuration(
    record: SessionRecord,
    meshes: tuple[Mesh, Mesh],
    map_source_to_target: np.ndarray,
    semilandmarks: int = DEFAULT_SEMILANDMARKS,
    pseudo: int = 0,
) -> Configuration:
    """The configuration of a refinement: ``record`` is the session as the job refined it, and its pseudo-landmarks
    are carried by the job's pointwise map ``map_source_to_target`` (a target file id per source file id, as the
    job's ``p2p_source_to_target.npy``)."""
    check_counts(semilandmarks, pseudo)
    mesh_M, mesh_N = meshes
    if len(map_source_to_target) != mesh_M.n_file_vertices:
        raise InvalidInput(
            f"the refinement's map has {len(map_source_to_target)} rows; the source has {mesh_M.n_file_vertices}"
        )
    if not pseudo:
        return session_configuration(record, meshes, semilandmarks)
    _check_pseudo(pseudo, mesh_M)
    on_M = farthest_point_sampling(mesh_M, pseudo)
    on_N = mesh_N.internal_ids(map_source_to_target[mesh_M.file_ids[on_M]], "mapped vertex")
    return session_configuration(record, meshes, semilandmarks, (on_M, on_N))


def _check_pseudo(pseudo: int, mesh: Mesh) -> None:
    if pseudo > mesh.n_vertices:
        raise InvalidInput(f"pseudo-landmarks: {pseudo} asked, the source has {mesh.n_vertices} vertices")


def check_counts(semilandmarks: int, pseudo: int) -> None:
    if not 0 <= semilandmarks <= MAX_SEMILANDMARKS:
        raise InvalidInput(f"semilandmarks per curve: 0 to {MAX_SEMILANDMARKS}, got {semilandmarks}")
    if not 0 <= pseudo <= MAX_PSEUDO_LANDMARKS:
        raise InvalidInput(f"pseudo-landmarks: 0 to {MAX_PSEUDO_LANDMARKS}, got {pseudo}")


def _paths(record: SessionRecord) -> tuple[list[np.ndarray], list[np.ndarray]]:
    source = [np.frombuffer(c.path_source, dtype=np.int32) for c in record.curves]
    target = [np.frombuffer(c.path_target, dtype=np.int32) for c in record.curves]
    return source, target


def _curve_layout(record: SessionRecord, semilandmarks: int) -> tuple[list[CurveLandmarks], list[str]]:
    n_curves = len(record.curves)
    curves, ends, sliders = [], [], []
    for i, curve in enumerate(record.curves):
        label = curve.spec.template_curve or curve.id
        first = 2 * n_curves + i * semilandmarks
        curves.append(CurveLandmarks(label, 2 * i, 2 * i + 1, range(first, first + semilandmarks)))
        ends += [f"{label}-start", f"{label}-end"]
        sliders += [f"{label}-s{j + 1}" for j in range(semilandmarks)]
    return curves, ends + sliders
