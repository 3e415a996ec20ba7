"""Check members: members with a known ground truth, against which each annotator's map of them is scored.

A ground truth follows the collection's map direction (template -> member): for every template vertex (file ids,
in order) the member vertex it corresponds to (file id; -1: unknown). It is read from a file (:func:`read_truth`):
``.npy`` (a 1-D integer array), ``.vts`` (1-based ids, first column, as the shared data's), or else text with one
0-based id per line (first column), and checked against both meshes (:func:`checked_truth`).

An annotation is scored (:func:`accuracy`) as the project scores maps (:func:`~curvefm.evaluation.truth_to_score`):
at the compared template vertices with a known partner, less those at either end of a curve the annotator gave
(on the template, or where its true partner is one of the annotator's ends on the member), the mean geodesic
distance on the member between the annotator's image and the true one, divided by sqrt(area of the member).
"""

from __future__ import annotations

import io
from dataclasses import dataclass

import numpy as np

from curvefm.collection.agreement import Annotated, mean_of_known
from curvefm.errors import InvalidInput
from curvefm.evaluation import GroundTruth, truth_to_score
from curvefm.evaluation.ground_truth import parse_int_column
from curvefm.geometry import Mesh, pair_geodesic_distances

NPY_MAGIC = b"\x93NUMPY"


def read_truth(data: bytes, filename: str) -> np.ndarray:
    """The ids of a ground-truth file (module doc) as 0-based file ids, one per template vertex."""
    if data.startswith(NPY_MAGIC):
        return _npy_ids(data, filename)
    if not filename.lower().endswith(".vts"):
        return parse_int_column(io.BytesIO(data), filename, 0, "vertex ids")
    ids = parse_int_column(io.BytesIO(data), filename, 0, "1-based vertex ids")
    if ids.size and ids.min() < 1:
        raise InvalidInput(f"{filename} contains id 0 or a negative id; .vts files are 1-based")
    return ids - 1


def _npy_ids(data: bytes, filename: str) -> np.ndarray:
    try:
        ids = np.load(io.BytesIO(data), allow_pickle=False)
    except (ValueError, OSError, EOFError) as exc:
        raise InvalidInput(f"{filename} is not a readable .npy array ({exc})") from None
    if ids.ndim != 1 or not np.issubdtype(ids.dtype, np.integer):
        raise InvalidInput(f"{filename} holds a {ids.ndim}-D {ids.dtype} array; expected 1-D integers")
    return ids.astype(np.int64)


def checked_truth(ids: np.ndarray, template: Mesh, member: Mesh) -> np.ndarray:
    """``ids`` when they are a ground truth from ``template`` to ``member`` (one member vertex, or -1, per template
    vertex; at least one known on both surfaces); :class:`InvalidInput` naming the first problem otherwise."""
    if ids.size != template.n_file_vertices:
        raise InvalidInput(
            f"the ground truth has {ids.size} rows; it needs one per template vertex ({template.n_file_vertices}), "
            "each the member vertex it corresponds to"
        )
    bad = np.flatnonzero((ids < -1) | (ids >= member.n_file_vertices))
    if bad.size:
        raise InvalidInput(
            f"row {bad[0]} of the ground truth names vertex {ids[bad[0]]}, out of range: the member has "
            f"{member.n_file_vertices} vertices (ids are 0-based, -1 for unknown)"
        )
    known = ids >= 0
    dropped = np.flatnonzero(known & (member.per_file_vertex(np.ones(member.n_vertices, bool), False)[ids] == 0))
    if dropped.size:
        raise InvalidInput(
            f"row {dropped[0]} of the ground truth names member vertex {ids[dropped[0]]}, which belongs to no face"
        )
    if not len(truth_pairs(ids, template, member)):
        raise InvalidInput("the ground truth gives no partner to any template vertex on the surface (all rows -1)")
    return ids


def truth_pairs(ids: np.ndarray, template: Mesh, member: Mesh) -> GroundTruth:
    """A checked ground truth (:func:`checked_truth`) as internal-id pairs template -> member, the rows of unknown
    partners and of template vertices on no face left out."""
    on_template = template.per_file_vertex(np.arange(template.n_vertices), -1)
    keep = (ids >= 0) & (on_template >= 0)
    partners = member.per_file_vertex(np.arange(member.n_vertices), -1)[ids[keep]]
    return GroundTruth(on_template[keep], partners, "member-truth", dense=True)


@dataclass(frozen=True)
class Accuracy:
    """One annotation's error on a check member."""

    annotation: Annotated
    error: float | None
    """Mean geodesic distance on the member from the annotator's images to the true ones, by sqrt(area) (None:
    no row to score, or all unreachable)."""
    scored: int
    """The template vertices it was scored at (with a known partner, at no curve end, on one component)."""
    unreachable: int
    """Scored template vertices whose image lies on another component of the member than the true one."""


def accuracy(
    annotation: Annotated, rows: np.ndarray, truth: GroundTruth, template_ends: dict[str, tuple[int, int]], member: Mesh
) -> Accuracy:
    """How far ``annotation``'s map (its images of the template vertices ``rows``) lies from ``truth`` (module doc).
    ``template_ends``: the template curves' ends (internal ids), by template curve."""
    given = [t for t in annotation.ends if t in template_ends]
    curves = [(np.array(template_ends[t]), np.array(annotation.ends[t])) for t in given]
    scored = truth_to_score(truth, curves)
    partner = np.full(max(int(rows.max(initial=-1)), int(scored.ids_X.max(initial=-1))) + 1, -1, dtype=np.int64)
    partner[scored.ids_X] = scored.ids_Y
    at = np.flatnonzero(partner[rows] >= 0)
    distances = pair_geodesic_distances(member, annotation.p2p[at], partner[rows[at]])
    reached = distances[np.isfinite(distances)]
    error = float(reached.mean() / np.sqrt(member.area)) if reached.size else None
    return Accuracy(annotation, error, int(reached.size), int(distances.size - reached.size))


@dataclass(frozen=True)
class AnnotatorAccuracy:
    annotator: str
    members: int
    """Check members the annotator annotated (with curves)."""
    error: float | None
    """The mean of their errors over those members (None: none scored)."""


def accuracy_by_annotator(scores: list[tuple[str, Accuracy]]) -> list[AnnotatorAccuracy]:
    """Per named annotator, by name, from ``(member, accuracy)``: their check members and mean error."""
    theirs: dict[str, list[tuple[str, Accuracy]]] = {}
    for member, score in scores:
        if score.annotation.annotator is not None:
            theirs.setdefault(score.annotation.annotator, []).append((member, score))
    return [
        AnnotatorAccuracy(name, len({m for m, _ in mine}), mean_of_known([s.error for _, s in mine]))
        for name, mine in sorted(theirs.items())
    ]
