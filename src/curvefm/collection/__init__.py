"""Collections: one template shape with its curves, drawn once, and many member shapes, each a session
(template -> member) whose curves answer the template curves; batch runs refine every member as a job, and a
run's maps come as one archive, member-to-member maps composed through the template.

* ``record``: the persisted :class:`CollectionRecord` (template curves, members, runs) and
  :class:`CollectionCreate`;
* the records are in the records' database (:class:`curvefm.records.collections.Collections`);
* ``editing``: :class:`CollectionEditor`, create / add members / answer a template curve / share / delete / runs;
* ``progress``: where each member and run stands (:class:`JobView` is how a queue's job is seen);
* ``archive``: a run's maps per member (:class:`MemberMaps`) as ``.npz`` or a zip of text files;
* ``composition``: member-to-member maps through the template;
* ``agreement``: how far two annotators' answers on a member lie apart (double annotation);
* ``checks``: check members' ground truth, and each annotation's accuracy against it.
"""

from curvefm.collection.agreement import (
    Annotated,
    AnnotatorAgreement,
    CurveEnds,
    PairAgreement,
    agreement,
    by_annotator,
    mean_of_known,
)
from curvefm.collection.archive import MemberMaps, composed, write_npz, write_zip
from curvefm.collection.checks import (
    Accuracy,
    AnnotatorAccuracy,
    accuracy,
    accuracy_by_annotator,
    checked_truth,
    read_truth,
    truth_pairs,
)
from curvefm.collection.composition import compose_functional, compose_pointwise
from curvefm.collection.editing import CollectionEditor, SubmitRefine
from curvefm.collection.progress import (
    JobView,
    MemberRunState,
    MemberStatus,
    RunStatus,
    archive_summary,
    member_status,
    run_maps,
    run_status,
)
from curvefm.collection.record import (
    CollectionCreate,
    CollectionRecord,
    Member,
    Run,
    RunMember,
    TemplateCurve,
    TemplateCurveSpec,
    UnknownCollection,
)

__all__ = [
    "Accuracy",
    "AnnotatorAccuracy",
    "accuracy",
    "accuracy_by_annotator",
    "checked_truth",
    "read_truth",
    "truth_pairs",
    "Annotated",
    "AnnotatorAgreement",
    "CurveEnds",
    "PairAgreement",
    "agreement",
    "by_annotator",
    "mean_of_known",
    "CollectionCreate",
    "CollectionEditor",
    "CollectionRecord",
    "JobView",
    "Member",
    "MemberMaps",
    "MemberRunState",
    "MemberStatus",
    "Run",
    "RunMember",
    "RunStatus",
    "SubmitRefine",
    "TemplateCurve",
    "TemplateCurveSpec",
    "UnknownCollection",
    "archive_summary",
    "compose_functional",
    "compose_pointwise",
    "composed",
    "member_status",
    "run_maps",
    "run_status",
    "write_npz",
    "write_zip",
]
