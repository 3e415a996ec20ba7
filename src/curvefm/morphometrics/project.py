"""A collection's correspondences as one configuration with a specimen per member (and, if asked, the template
first): the template curves in the template's order, each resampled to the same number of semilandmarks on every
member, and pseudo-landmarks chosen once on the template by farthest-point sampling and carried to each member by
that member's map. The landmarks' order is a session's (:mod:`.configuration`): endpoints, semilandmarks, then
pseudo-landmarks."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from curvefm.errors import InvalidInput
from curvefm.geometry import Mesh, farthest_point_sampling
from curvefm.morphometrics.configuration import Configuration, check_counts, session_configuration
from curvefm.pointwise import pointwise_from_both
from curvefm.session import SessionRecord

if TYPE_CHECKING:
    from curvefm.session import SessionEditor


@dataclass(frozen=True)
class MemberShape:
    """One member: its name (the specimen's ``ID``), its session (template -> member), its mesh, and the member
    vertex (internal id) of each pseudo-landmark (None without pseudo-landmarks)."""

    name: str
    record: SessionRecord
    mesh: Mesh
    pseudo: np.ndarray | None = None


def missing_curves(record: SessionRecord, template_curves: list[str]) -> list[str]:
    """The template curves (ids) that the member session does not answer."""
    answered = {curve.spec.template_curve for curve in record.curves}
    return [curve for curve in template_curves if curve not in answered]


def template_pseudo(template: Mesh, count: int) -> np.ndarray:
    """``count`` template vertices (internal ids) spread by farthest-point sampling: the same for every member."""
    if count > template.n_vertices:
        raise InvalidInput(f"pseudo-landmarks: {count} asked, the template has {template.n_vertices} vertices")
    return farthest_point_sampling(template, count)


def live_mapped(editor: SessionEditor, session_id: str, on_template: np.ndarray) -> np.ndarray:
    """The member vertex (internal id) the member session's live maps give each template vertex ``on_template``
    (the nearest neighbour of both functional maps, as a session's live export)."""
    with editor.live.using(session_id) as live:
        live.solver.settle()
        solver = live.solver
        C_MN, C_NM = solver.C_MN, solver.C_NM
    mapped = pointwise_from_both(C_NM, C_MN, solver.basis_N, solver.basis_M, rows=on_template)
    return np.asarray(mapped, dtype=np.int64)


def run_mapped(template: Mesh, member: Mesh, map_template_to_member: np.ndarray, on_template: np.ndarray) -> np.ndarray:
    """As :func:`live_mapped`, by a run's pointwise map (a member file id per template file id)."""
    if len(map_template_to_member) != template.n_file_vertices:
        raise InvalidInput(
            f"the run's map has {len(map_template_to_member)} rows; the template has {template.n_file_vertices}"
        )
    return member.internal_ids(map_template_to_member[template.file_ids[on_template]], "mapped vertex")


def project_configuration(
    template: Mesh,
    template_name: str,
    template_curves: list[str],
    members: list[MemberShape],
    semilandmarks: int,
    on_template: np.ndarray | None = None,
    with_template: bool = False,
) -> Configuration:
    """The configuration of every member (each must answer every template curve: :func:`missing_curves`), the
    template first when ``with_template``; ``on_template``: the pseudo-landmarks' template vertices."""
    check_counts(semilandmarks, 0)
    if not members:
        raise InvalidInput("no member to export")
    configurations = [
        session_configuration(
            _in_template_order(member.record, template_curves),
            (template, member.mesh),
            semilandmarks,
            None if on_template is None or member.pseudo is None else (on_template, member.pseudo),
        )
        for member in members
    ]
    first = configurations[0]
    names = [member.name for member in members]
    points = [configuration.points[1] for configuration in configurations]
    vertices = [] if on_template is None else [m.mesh.file_ids[m.pseudo] for m in members if m.pseudo is not None]
    origin = np.empty(0, dtype=np.int64) if on_template is None else template.file_ids[on_template]
    if with_template:
        names, points = [template_name, *names], [first.points[0], *points]
        vertices = [origin, *vertices] if on_template is not None else vertices
    return Configuration(
        tuple(names), tuple(points), first.labels, first.curves, first.pseudo, 0, tuple(vertices), origin
    )


def _in_template_order(record: SessionRecord, template_curves: list[str]) -> SessionRecord:
    """The member session with only the curves that answer template curves, in the template's order."""
    by_template = {curve.spec.template_curve: curve for curve in record.curves if curve.spec.template_curve}
    return record.model_copy(update={"curves": [by_template[curve] for curve in template_curves]})
