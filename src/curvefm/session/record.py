"""Session records: what a session stores on disk (:func:`curvefm.session.restore.build_solver` rebuilds its solver).

A record holds the shape pair, the parameters and every curve with its traced paths in **file** vertex ids
(the ids a user reads off the mesh files). It is written atomically on every change
(:class:`curvefm.records.sessions.Sessions`); the refinement job receives a copy of it, so both rebuild
exactly the same ``CurveMapSolver``.

The solver's parameters ``k``, ``alpha``, ``samples`` and ``energy`` are validated here, once, by the types
below, which the request for a new session (:class:`SessionCreate`) and the record share.
"""

from __future__ import annotations

from array import array
from typing import TYPE_CHECKING, Annotated, Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, PlainSerializer, PlainValidator

from curvefm.errors import NotFound, shown
from curvefm.fmap import DEFAULT_ALPHA, DEFAULT_K, DEFAULT_SAMPLES
from curvefm.session.curves import MAX_VERTEX_ID, CurveSpec, VertexId

MapSize = Annotated[int, Field(ge=1, description="basis functions per shape: the maps are k x k")]
Alpha = Annotated[float, Field(ge=0, allow_inf_nan=False, description="weight of Laplacian commutativity")]
Samples = Annotated[int, Field(ge=2, le=10_000, description="samples per curve")]
Sharing = Literal["private", "read", "edit"]
NAME_LENGTH = 200
"""The longest session name (the column's width)."""
Energy = Literal["combined", "curves"]
ENERGY_DESCRIPTION = (
    "the energy the maps minimise: combined (curves, wave kernel signatures and wave kernel maps along the curves, "
    "Laplacian commutativity) or curves (the paper's curve constraints and Laplacian commutativity alone)"
)
SHARING_DESCRIPTION = (
    "who besides the owner (and admins) may use the session: private (nobody), read (every user may read it and "
    "refine from it), edit (every user may also change its curves); only the owner or an admin changes this"
)


if TYPE_CHECKING:
    IdArray = array[int]
else:  # array is not subscriptable at run time before Python 3.12
    IdArray = array


def _vertex_path(value: Any) -> IdArray:
    try:
        if isinstance(value, array) and value.typecode == "i":
            path = value
        else:  # array() checks each id fits (a list is the fast input: pydantic hands the JSON over as one)
            path = array("i", value.tolist() if isinstance(value, np.ndarray) else value)
    except (TypeError, OverflowError):
        raise ValueError(f"a path is a list of vertex ids, 0 to {MAX_VERTEX_ID}") from None
    if path and np.frombuffer(path, dtype=np.int32).min() < 0:
        raise ValueError(f"a path is a list of vertex ids, 0 to {MAX_VERTEX_ID}")
    return path


VertexPath = Annotated[
    IdArray,
    PlainValidator(_vertex_path, json_schema_input_type=list[VertexId]),
    PlainSerializer(array.tolist, return_type=list[int]),
]
"""A vertex path (file ids, start first): a list of ids in JSON, a compact int32 ``array`` in memory (4 bytes an
id instead of a Python list's 36)."""


class UnknownSession(NotFound):
    """No session has this id (or the id cannot name one)."""

    def __init__(self, session_id: str):
        self.session_id = session_id
        super().__init__(f"no session with id '{shown(session_id)}'")


class SessionCreate(BaseModel):
    """A new session on two stored shapes (ids), with the parameters of its solver."""

    model_config = ConfigDict(extra="forbid")
    source: str = Field(description="shape id of M")
    target: str = Field(description="shape id of N")
    k: MapSize = DEFAULT_K
    alpha: Alpha = DEFAULT_ALPHA
    tracer: str = Field("geodesic", description="default tracer for curves that name none")
    samples: Samples = DEFAULT_SAMPLES
    energy: Energy = Field("combined", description=ENERGY_DESCRIPTION)
    basis_plugin: str = "laplace-beltrami"
    basis_params: dict[str, Any] = Field(default_factory=dict)
    name: str = Field(
        "", max_length=NAME_LENGTH, description="what the lists show; empty: 'SOURCE -> TARGET', the shapes' names"
    )
    sharing: Sharing = Field("private", description=SHARING_DESCRIPTION)


class CurveRecord(BaseModel):
    """One stored curve pair: the user's input and the traced paths (file vertex ids, start first)."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    id: str
    spec: CurveSpec
    tracer: str = Field(description="tracer actually used (the session default when the spec names none)")
    path_source: VertexPath
    path_target: VertexPath


class SessionRecord(BaseModel):
    # frozen: a parsed record is shared by the requests that read the same stored bytes (Sessions.read)
    model_config = ConfigDict(extra="forbid", frozen=True)
    id: str
    name: str = ""
    owner: str = Field("", description="the user who created it (empty: made before users existed; admins only)")
    sharing: Sharing = Field("private", description=SHARING_DESCRIPTION)
    source: str = Field(description="shape id of M, the source")
    target: str = Field(description="shape id of N, the target")
    k: MapSize
    alpha: Alpha
    samples: Samples
    energy: Energy = Field(
        "curves",
        description=ENERGY_DESCRIPTION + "; records written before energies existed "
        "have none and keep curves, so their maps do not change",
    )
    tracer: str
    basis_plugin: str
    basis_params: dict[str, Any]
    curves: list[CurveRecord] = Field(default_factory=list)
    next_curve: int = 1
    revision: int = Field(0, description="increases with every write of the record")
    created_at: float
    updated_at: float
