"""The agreement report of a collection (:mod:`curvefm.collection.agreement`, :mod:`curvefm.collection.checks`):
what ``GET /collections/{id}/agreement`` answers, and what a run's archive (the service's and ``curvefm collection
export``'s) holds in its ``summary.json``.
"""

from __future__ import annotations

from itertools import combinations
from typing import Any

import numpy as np

from curvefm.collection import (
    Accuracy,
    Annotated,
    AnnotatorAgreement,
    CollectionEditor,
    CollectionRecord,
    PairAgreement,
    accuracy,
    accuracy_by_annotator,
    agreement,
    by_annotator,
    mean_of_known,
    truth_pairs,
)
from curvefm.geometry import Mesh, farthest_point_sampling
from curvefm.pointwise import pointwise_from_both
from curvefm.records.collections import Annotation
from curvefm.service.models import (
    AgreementReport,
    AnnotationAccuracyView,
    AnnotatorAccuracyView,
    AnnotatorAgreementView,
    CheckReport,
    CurveEndsAgreement,
    MemberAccuracy,
    MemberAgreement,
    PairAgreementView,
)
from curvefm.session import LiveSessions


def archive_agreement(
    collections: CollectionEditor, record: CollectionRecord, points: int, threshold: float, checks: bool
) -> dict[str, Any] | None:
    """The agreement report for a run's ``summary.json`` (:func:`agreement_report`, with the check members'
    accuracy when ``checks``), or None when the collection has neither a double annotation nor (with ``checks``) a
    check member."""
    doubled = any(a.further for a in collections.records.annotations(record.id))
    checks = checks and bool(collections.records.check_members(record.id))
    if not (doubled or checks):
        return None
    return agreement_report(collections, record, points, threshold, checks).model_dump()


def agreement_report(
    collections: CollectionEditor, record: CollectionRecord, points: int, threshold: float, checks: bool = False
) -> AgreementReport:
    """The agreement between the collection's annotators (``GET /collections/{id}/agreement``) at ``points``
    template vertices (``CURVEFM_AGREEMENT_POINTS``), members flagged above ``threshold``
    (``CURVEFM_AGREEMENT_THRESHOLD``); with ``checks``, their accuracy on the check members too (for those who
    manage the collection only)."""
    records, live = collections.records, collections.sessions.live
    by_member: dict[str, list[Annotation]] = {}
    for annotation in records.annotations(record.id):
        if collections.sessions.record(annotation.session_id).curves:
            by_member.setdefault(annotation.member_id, []).append(annotation)
    twice = [member for member, annotations in by_member.items() if len(annotations) > 1]
    check_members = records.check_members(record.id) if checks else []
    template = live.mesh(record.template, "template")
    rows = farthest_point_sampling(template, min(points, template.n_vertices))
    answers = {
        member: [(a, _annotated(live, a, rows)) for a in annotations]
        for member, annotations in by_member.items()
        if member in twice or member in check_members
    }
    compared = {member: _member_pairs(live, record, member, [a for _, a in answers[member]]) for member in twice}
    members = [_member_agreement(member, pairs, threshold) for member, pairs in compared.items()]
    annotators = by_annotator([(member, pair) for member, pairs in compared.items() for pair in pairs])
    return AgreementReport(
        members=members,
        annotators=[_annotator_view(a) for a in annotators],
        map_distance=mean_of_known([m.map_distance for m in members]),
        endpoint_distance=mean_of_known([pair.endpoint_distance for pairs in compared.values() for pair in pairs]),
        threshold=threshold,
        points=len(rows),
        flagged=[m.member for m in members if m.flagged],
        checks=_check_report(collections, record, template, rows, check_members, answers) if check_members else None,
    )


def _member_pairs(
    live: LiveSessions, record: CollectionRecord, member_id: str, answers: list[Annotated]
) -> list[PairAgreement]:
    member = live.mesh(record.member(member_id).shape, "member")
    return [agreement(a, b, member) for a, b in combinations(answers, 2)]


def _check_report(
    collections: CollectionEditor,
    record: CollectionRecord,
    template: Mesh,
    rows: np.ndarray,
    check_members: list[str],
    answers: dict[str, list[tuple[Annotation, Annotated]]],
) -> CheckReport:
    """Each annotation of a check member scored against its ground truth (:func:`curvefm.collection.accuracy`)."""
    template_ends = {}
    for curve in record.curves:
        path = template.internal_ids(np.asarray(curve.path), "template curve vertex")
        template_ends[curve.id] = (int(path[0]), int(path[-1]))
    members, scores = [], []
    for member_id in check_members:
        mesh = collections.sessions.live.mesh(record.member(member_id).shape, "member")
        stored = collections.records.truth(record.id, member_id)
        if stored is None:  # taken away meanwhile
            continue
        truth = truth_pairs(stored.truth, template, mesh)
        mine = [(a, accuracy(answer, rows, truth, template_ends, mesh)) for a, answer in answers.get(member_id, [])]
        scores += [(member_id, score) for _, score in mine]
        members.append(MemberAccuracy(member=member_id, annotations=[_accuracy_view(a, s) for a, s in mine]))
    return CheckReport(
        members=members,
        annotators=[AnnotatorAccuracyView(**vars(a)) for a in accuracy_by_annotator(scores)],
        error=mean_of_known([score.error for _, score in scores]),
    )


def _accuracy_view(annotation: Annotation, score: Accuracy) -> AnnotationAccuracyView:
    return AnnotationAccuracyView(
        annotator=annotation.user,
        session=annotation.session_id,
        further=annotation.further,
        error=score.error,
        scored=score.scored,
        unreachable=score.unreachable,
    )


def _member_agreement(member_id: str, pairs: list[PairAgreement], threshold: float) -> MemberAgreement:
    distance = mean_of_known([p.map_distance for p in pairs])
    flagged = distance is not None and distance > threshold
    views = [_pair_view(p) for p in pairs]
    return MemberAgreement(member=member_id, pairs=views, map_distance=distance, flagged=flagged)


def _annotator_view(a: AnnotatorAgreement) -> AnnotatorAgreementView:
    return AnnotatorAgreementView(**vars(a))


def _annotated(live: LiveSessions, annotation: Annotation, rows: np.ndarray) -> Annotated:
    """An annotation's live map at the template vertices ``rows`` and its curves' ends on the member (internal
    ids)."""
    with live.using(annotation.session_id) as session:
        session.solver.settle()
        solver, record, member = session.solver, session.record, session.pair.mesh_N
        p2p = pointwise_from_both(solver.C_NM, solver.C_MN, solver.basis_N, solver.basis_M, rows=rows)
    ends = {}
    for curve in record.curves:
        if curve.spec.template_curve:
            path = member.internal_ids(np.asarray(curve.path_target), "path vertex")
            ends[curve.spec.template_curve] = (int(path[0]), int(path[-1]))
    return Annotated(annotation.user, annotation.session_id, np.asarray(p2p, dtype=np.int64), ends)


def _pair_view(pair: PairAgreement) -> PairAgreementView:
    return PairAgreementView(
        a=pair.a.annotator,
        b=pair.b.annotator,
        session_a=pair.a.session,
        session_b=pair.b.session,
        map_distance=pair.map_distance,
        unreachable=pair.unreachable,
        endpoint_distance=pair.endpoint_distance,
        curves=[CurveEndsAgreement(**vars(c)) for c in pair.curves],
    )
