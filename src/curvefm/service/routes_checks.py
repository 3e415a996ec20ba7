"""Check members: a manager gives a member its ground truth (:mod:`curvefm.collection.checks`), and the agreement
report scores each annotation of it against the truth (for those who manage the collection only).

The truth is the managers': giving, reading back and taking it away need ``manage`` (an owner, a manager, an
admin); everyone else is refused before anything about the member is looked up, so an annotator cannot tell a
check member from another (blind checks, docs/decisions.md).
"""

from __future__ import annotations

from typing import Annotated

import numpy as np
from fastapi import APIRouter, File, Response, UploadFile
from starlette.concurrency import run_in_threadpool

from curvefm.collection import checked_truth, read_truth
from curvefm.errors import NotFound
from curvefm.records.collections import Truth
from curvefm.service import routes_reviews
from curvefm.service.auth import AUTHENTICATED, CurrentUser
from curvefm.service.deps import Services, ServicesDep
from curvefm.service.errors import error_responses
from curvefm.service.models import TruthView
from curvefm.service.openapi import SchemaRoute
from curvefm.service.permissions import check_collection
from curvefm.service.routes_reviews import ERRORS

router = APIRouter(tags=["collections"], route_class=SchemaRoute, dependencies=AUTHENTICATED)
router.responses = routes_reviews.router.responses  # as the other collection routes
TRUTH = "/collections/{collection_id}/members/{member_id}/truth"


@router.put(
    TRUTH,
    response_model=TruthView,
    responses={
        **ERRORS,
        **error_responses(
            400, 413, described={400: "a file that is not a ground truth of the template and the member (it says why)"}
        ),
    },
)
async def put_truth(
    collection_id: str,
    member_id: str,
    services: ServicesDep,
    user: CurrentUser,
    file: Annotated[
        UploadFile,
        File(
            description="per template vertex (file ids, in order) the member vertex it corresponds to: .npy (1-D "
            "integers), .vts (1-based, first column) or text with one 0-based id per line; -1: unknown"
        ),
    ],
) -> TruthView:
    """Make the member a check member: its ground truth, template -> member, as the collection's maps go (one row
    per template vertex; ``CURVEFM_MAX_BODY_BYTES`` at most). Replaces one it had. The agreement report then scores
    every annotation of the member against it. An owner, a manager or an admin; audited as ``collection.truth``
    (without the truth)."""
    data, filename = await file.read(), file.filename or "truth"

    def store() -> TruthView:
        check_collection(services, user, collection_id, "manage")
        record = services.collections.record(collection_id)
        member = record.member(member_id)
        template, mesh = services.live.mesh(record.template, "template"), services.live.mesh(member.shape, "member")
        ids = checked_truth(read_truth(data, filename), template, mesh)
        replaced = services.collections.records.set_truth(collection_id, member_id, ids, user.id)
        view = _truth_view(_stored_truth(services, collection_id, member_id))
        detail = {"member": member_id, "rows": view.rows, "known": view.known, "replaced": replaced}
        services.audit.record(user.name, "collection.truth", collection_id, detail)
        return view

    return await run_in_threadpool(store)


@router.get(TRUTH, response_model=TruthView, responses=ERRORS)
def get_truth(collection_id: str, member_id: str, services: ServicesDep, user: CurrentUser) -> TruthView:
    """The member's ground truth (404: it is no check member): an owner, a manager or an admin."""
    check_collection(services, user, collection_id, "manage")
    truth = _stored_truth(services, collection_id, member_id)
    return _truth_view(truth).model_copy(update={"truth": truth.truth.tolist()})


@router.delete(TRUTH, status_code=204, responses=ERRORS)
def delete_truth(collection_id: str, member_id: str, services: ServicesDep, user: CurrentUser) -> Response:
    """Take the member's ground truth away (404: it had none): it is no check member any more. An owner, a manager
    or an admin; audited as ``collection.truth_removed``."""
    check_collection(services, user, collection_id, "manage")
    services.collections.record(collection_id).member(member_id)
    if not services.collections.records.remove_truth(collection_id, member_id):
        raise NotFound(f"member {member_id} of collection {collection_id} has no ground truth")
    services.audit.record(user.name, "collection.truth_removed", collection_id, {"member": member_id})
    return Response(status_code=204)


def _stored_truth(services: Services, collection_id: str, member_id: str) -> Truth:
    services.collections.record(collection_id).member(member_id)
    truth = services.collections.records.truth(collection_id, member_id)
    if truth is None:
        raise NotFound(f"member {member_id} of collection {collection_id} has no ground truth")
    return truth


def _truth_view(truth: Truth) -> TruthView:
    known = int(np.count_nonzero(truth.truth >= 0))
    return TruthView(
        member=truth.member_id, rows=int(truth.truth.size), known=known, set_by=truth.set_by, set_at=truth.set_at
    )
