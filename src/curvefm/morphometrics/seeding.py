"""Markups made curve pairs: every point snapped to the nearest vertex of its mesh, each snap's distance reported,
and points farther than a tolerance (relative to the mesh's size, sqrt(area)) refused by name."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal, TypeVar

import numpy as np
from pydantic import BaseModel, Field
from scipy.spatial import cKDTree

from curvefm.errors import InvalidInput
from curvefm.geometry import Mesh
from curvefm.morphometrics.reading import MarkupPairs
from curvefm.session import CurveSpec, SessionLimits

DEFAULT_SNAP_TOLERANCE = 0.05
"""How far a point may be from its nearest vertex, in units of the mesh's sqrt(area)."""
Side = Literal["source", "target"]
T = TypeVar("T")


class SnappedPoint(BaseModel):
    """One markup point and the vertex it was snapped to."""

    side: Side
    file: str = Field(description="the file it came from")
    markup: str = Field(description="the curve's name, or 'landmarks'")
    label: str
    position: list[float] = Field(description="as read, in the mesh's frame (LPS)")
    vertex: int = Field(description="the nearest vertex (file id)")
    distance: float = Field(description="from the point to the vertex, in the mesh's units")
    relative_distance: float = Field(description="the distance in units of the mesh's sqrt(area)")


class SeededCurve(BaseModel):
    """A curve pair made from markups: its name and the spec that adds it to a session."""

    name: str
    spec: CurveSpec


class Seeding(BaseModel):
    curves: list[SeededCurve]
    points: list[SnappedPoint]
    unpaired: list[str] = Field(description="curves and landmarks only one of the two files has (left out)")


def _tree(mesh: Mesh) -> cKDTree:
    return mesh.derived.get("vertex-tree", lambda: cKDTree(mesh.vertices))


@dataclass(frozen=True)
class Tolerance:
    """How far a point may be from its vertex (units of sqrt(area)), and the setting that says so."""

    limit: float = DEFAULT_SNAP_TOLERANCE
    setting: str = "CURVEFM_MARKUP_SNAP_TOLERANCE"


def _snap(
    mesh: Mesh, side: Side, file: str, markup: str, labels: list[str], points: np.ndarray, tolerance: Tolerance
) -> list[SnappedPoint]:
    found = _tree(mesh).query(points)
    distances, nearest = np.atleast_1d(found[0]), np.atleast_1d(found[1])
    scale = float(np.sqrt(mesh.area))
    snapped = []
    for label, point, distance, vertex in zip(labels, points, distances, nearest, strict=True):
        relative = float(distance) / scale
        if relative > tolerance.limit:
            raise InvalidInput(
                f"{side} file {file}: point '{label}' of '{markup}' at {[round(float(v), 6) for v in point]} is "
                f"{float(distance):.6g} from the nearest vertex of mesh '{mesh.name}', {relative:.3g} sqrt(area); "
                f"more than the tolerance {tolerance.limit:g} sqrt(area) ({tolerance.setting}): is the file "
                "for this mesh, in its coordinates?"
            )
        file_id = int(mesh.file_ids[vertex])
        snapped.append(
            SnappedPoint(
                side=side,
                file=file,
                markup=markup,
                label=label,
                position=point.tolist(),
                vertex=file_id,
                distance=float(distance),
                relative_distance=relative,
            )
        )
    return snapped


def _sides(meshes: tuple[Mesh, Mesh], of: tuple[T, T]) -> list[tuple[Mesh, Side, T]]:
    return [(meshes[0], "source", of[0]), (meshes[1], "target", of[1])]


def _waypoints(points: list[SnappedPoint], name: str, side: Side) -> list[int]:
    """The snapped vertices in order, a vertex repeated by neighbouring points kept once."""
    ids = [p.vertex for i, p in enumerate(points) if i == 0 or p.vertex != points[i - 1].vertex]
    if len(set(ids)) < 2:
        raise InvalidInput(
            f"curve '{name}' has {len(points)} points on the {side}, snapped to {len(set(ids))} vertices: a curve "
            "needs two different ones"
        )
    return ids


def check_limits(seeding: Seeding, limits: SessionLimits, curves_now: int) -> None:
    """Refuse, before any curve is added, what the session's limits would refuse midway through the import."""
    count = curves_now + len(seeding.curves)
    limits.check("max_curves", count, f"{count} curves in the session with the {len(seeding.curves)} imported")
    for seeded in seeding.curves:
        for side, ids in (("source", seeded.spec.source), ("target", seeded.spec.target)):
            limits.check("max_waypoints", len(ids), f"{len(ids)} waypoints on the {side} of curve '{seeded.name}'")


def seed_curves(
    pairs: MarkupPairs,
    meshes: tuple[Mesh, Mesh],
    tolerance: Tolerance = Tolerance(),
    join_landmarks: bool = False,
) -> Seeding:
    """Curve specs from ``pairs``: each curve's points snapped to vertices become its waypoints (the session's
    tracer joins them); with ``join_landmarks`` each two consecutive paired landmarks also become a curve."""
    curves, report = [], []
    for name, on_M, on_N in pairs.curves:
        snapped = [
            _snap(mesh, side, markup.file, name, markup.labels, markup.points, tolerance)
            for mesh, side, markup in _sides(meshes, (on_M, on_N))
        ]
        report += snapped[0] + snapped[1]
        spec = CurveSpec(source=_waypoints(snapped[0], name, "source"), target=_waypoints(snapped[1], name, "target"))
        curves.append(SeededCurve(name=name, spec=spec))
    landmarks = _snapped_landmarks(pairs, meshes, tolerance)
    report += [point for pair in landmarks for point in pair]
    if join_landmarks:
        for (a_M, a_N), (b_M, b_N) in zip(landmarks, landmarks[1:], strict=False):
            if a_M.vertex != b_M.vertex and a_N.vertex != b_N.vertex:
                spec = CurveSpec(source=[a_M.vertex, b_M.vertex], target=[a_N.vertex, b_N.vertex])
                curves.append(SeededCurve(name=f"{a_M.label}-{b_M.label}", spec=spec))
    return Seeding(curves=curves, points=report, unpaired=pairs.unpaired)


def _snapped_landmarks(
    pairs: MarkupPairs, meshes: tuple[Mesh, Mesh], tolerance: Tolerance
) -> list[tuple[SnappedPoint, SnappedPoint]]:
    if not pairs.landmarks:
        return []
    labels = [label for label, _, _ in pairs.landmarks]
    sides = [
        _snap(mesh, side, file, "landmarks", labels, np.array([pair[index] for pair in pairs.landmarks]), tolerance)
        for (mesh, side, file), index in zip(_sides(meshes, pairs.files), (1, 2), strict=True)
    ]
    return list(zip(sides[0], sides[1], strict=True))
