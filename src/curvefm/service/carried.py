"""The transferred function an edit's answer carries (``?carry=``), so that a click costs the page one request:
rows quantised to 16 bits per value between each column's least and greatest value (a texture coordinate off by at
most 1/131,070 of its range, well under a texel of an 8k texture) and base64-encoded, about 1.5x smaller than the
float32 rows of ``GET /sessions/{id}/transfer``."""

from __future__ import annotations

import base64
from typing import Literal

import numpy as np
from pydantic import BaseModel, Field

from curvefm.session import Transferred

LEVELS = 65535
CarriedKind = Literal["uv", "xyz"]


class CarriedFunction(BaseModel):
    """A function on the source carried to the target, as ``GET /sessions/{id}/transfer`` gives it, compactly."""

    function: CarriedKind
    revision: int = Field(description="the session revision the map had")
    rows: int = Field(description="target vertices (as the transfer's resolution asked)")
    columns: int
    solve_ms: float = Field(description="milliseconds spent solving the map for it (0: already solved)")
    prior_pending: bool = Field(description="the map of this revision will still improve: read the transfer shortly")
    offset: list[float] = Field(description="per column: the value of code 0")
    step: list[float] = Field(description="per column: the value of one code step (value = offset + step * code)")
    codes: str = Field(description="base64 of little-endian uint16 codes, rows x columns, row-major")


def carried(function: CarriedKind, transferred: Transferred) -> CarriedFunction:
    n, columns = transferred.rows.shape
    # column by column: reducing a few-column array along its rows strides through memory (a third of the time)
    values = np.ascontiguousarray(transferred.rows.T, dtype=np.float64)
    low = values.min(axis=1) if n else np.zeros(columns)
    span = (values.max(axis=1) - low) if n else np.zeros(columns)
    step = np.where(span > 0, span / LEVELS, 1.0)
    codes = np.empty((n, columns), dtype="<u2")
    for column in range(columns):
        values[column] -= low[column]
        values[column] /= step[column]
        codes[:, column] = np.rint(values[column], out=values[column])
    return CarriedFunction(
        function=function,
        revision=transferred.revision,
        rows=n,
        columns=columns,
        solve_ms=round(transferred.solve_ms, 3),
        prior_pending=transferred.prior_pending,
        offset=low.tolist(),
        step=step.tolist(),
        codes=base64.b64encode(codes.tobytes()).decode("ascii"),
    )


def decoded(answer: CarriedFunction) -> np.ndarray:
    """The rows (float64, ``rows x columns``) that ``answer`` stands for."""
    codes = np.frombuffer(base64.b64decode(answer.codes), dtype="<u2").reshape(answer.rows, answer.columns)
    return np.asarray(answer.offset) + codes * np.asarray(answer.step)
