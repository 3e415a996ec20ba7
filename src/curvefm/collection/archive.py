"""A run's maps, member by member, read from the members' refinement results, and written as one archive.

Directions: the template is every member session's source. ``C_template_to_member`` (k x k) takes coefficients on
the template to coefficients on the member; ``map_member_to_template[i]`` is the template vertex of the member's
vertex i (0-based file ids, -1 for a vertex of no face), ``map_template_to_member`` the other way.
"""

from __future__ import annotations

import io
import json
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any, BinaryIO

import numpy as np

from curvefm.collection.composition import compose_functional, compose_pointwise

RESULT_FILES = {
    "C_template_to_member": "C_source_to_target.npy",
    "C_member_to_template": "C_target_to_source.npy",
    "map_member_to_template": "p2p_target_to_source.npy",
    "map_template_to_member": "p2p_source_to_target.npy",
}
"""Archive array -> the refinement job's result file it is read from."""


@dataclass(frozen=True)
class MemberMaps:
    member: str
    shape: str
    session: str
    job: str
    revision: int
    arrays: dict[str, np.ndarray]
    """The arrays of :data:`RESULT_FILES`, by archive name."""
    report: dict[str, Any]
    """The job's report on its maps: quality figures, which maps were kept and why."""

    def summary(self) -> dict[str, Any]:
        fields = {"shape": self.shape, "session": self.session, "job": self.job, "revision": self.revision}
        return {"member": self.member, **fields, **self.report}


def load_member_maps(
    folder: Path, member: str, shape: str, session: str, job: str, result: dict[str, Any]
) -> MemberMaps:
    """A member's maps from its refinement job's result ``folder`` and ``result`` (the job's return value)."""
    arrays = {name: np.load(folder / file) for name, file in RESULT_FILES.items()}
    report: dict[str, Any] = {key: result[key] for key in ("kept", "reason", "quality", "converter") if key in result}
    return MemberMaps(member, shape, session, job, result.get("revision", 0), arrays, report)


def composed(a: MemberMaps, b: MemberMaps) -> tuple[np.ndarray, np.ndarray]:
    """``(map_a_to_b, C_a_to_b)``: a's vertices carried to b's through the template, and the functional map."""
    p2p = compose_pointwise(a.arrays["map_member_to_template"], b.arrays["map_template_to_member"])
    return p2p, compose_functional(a.arrays["C_member_to_template"], b.arrays["C_template_to_member"])


def write_npz(out: str | Path | BinaryIO, maps: list[MemberMaps], summary: dict[str, Any]) -> None:
    """``<member>/<array>`` for every member, and ``summary.json`` (the run, and per member its quality)."""
    # Any: numpy's savez_compressed types **kwds together with its allow_pickle flag
    arrays: dict[str, Any] = {f"{m.member}/{name}": array for m in maps for name, array in m.arrays.items()}
    arrays["summary.json"] = np.array(json.dumps(summary))
    np.savez_compressed(out, **arrays)


def write_zip(out: str | Path | BinaryIO, maps: list[MemberMaps], summary: dict[str, Any]) -> None:
    """The same as text: ``<member>/<array>.txt`` (matrices row by row, maps one id a line) and ``summary.json``."""
    with zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as archive:
        for m in maps:
            for name, array in m.arrays.items():
                text = io.StringIO()
                np.savetxt(text, array, fmt="%d" if array.dtype.kind in "iu" else "%.17g")
                archive.writestr(f"{m.member}/{name}.txt", text.getvalue())
        archive.writestr("summary.json", json.dumps(summary, indent=1))
