"""3D Slicer markups read: ``.mrk.json`` (curves and fiducials) and the older fiducial CSV ``.fcsv``, positions
brought to the frame the mesh files have (``LPS``, as Slicer loads meshes: ``RAS`` points get x and y negated);
and the markups of a source file paired with those of a target file."""

from __future__ import annotations

import csv
import io
import json
import math
from collections import Counter
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from curvefm.errors import InvalidInput

CURVE_TYPES = ("Curve", "ClosedCurve", "Line")
POINT_TYPES = ("Fiducial",)
TO_LPS = {"LPS": np.array([1.0, 1.0, 1.0]), "RAS": np.array([-1.0, -1.0, 1.0])}
FCSV_SYSTEMS = {"0": "RAS", "1": "LPS", "RAS": "RAS", "LPS": "LPS"}  # older files give Slicer's enum value


@dataclass(frozen=True)
class Markup:
    """A curve (``kind="curve"``, points in order) or a list of landmarks (``"landmarks"``) from ``file``."""

    kind: str
    name: str
    labels: list[str]
    points: np.ndarray  # (n, 3), LPS
    file: str = ""


@dataclass(frozen=True)
class MarkupPairs:
    """Curves paired by name (or by order), landmarks by label: ``(name, source markup, target markup)`` and
    ``(label, source point, target point)``; ``unpaired`` names what only one file has."""

    curves: list[tuple[str, Markup, Markup]]
    landmarks: list[tuple[str, np.ndarray, np.ndarray]]
    unpaired: list[str] = field(default_factory=list)
    files: tuple[str, str] = ("", "")


def read_markups(data: bytes, file: str) -> list[Markup]:
    """The curves and landmarks of a ``.mrk.json`` or ``.fcsv`` file (told apart by their content)."""
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise InvalidInput(f"{file}: not a text file (a Slicer .mrk.json or .fcsv is UTF-8 text)") from None
    if text.lstrip().startswith("#"):
        return [_read_fcsv(text, file)]
    return _read_json(text, file)


def _read_json(text: str, file: str) -> list[Markup]:
    try:
        document = json.loads(text)
    except json.JSONDecodeError as exc:
        raise InvalidInput(f"{file}: neither Slicer markups JSON nor a .fcsv: {exc}") from None
    if not isinstance(document, dict) or not isinstance(document.get("markups"), list):
        raise InvalidInput(f"{file}: Slicer markups JSON has a 'markups' list at its top level; this has none")
    return [markup for i, item in enumerate(document["markups"]) if (markup := _markup(item, i, file)) is not None]


def _markup(item: Any, index: int, file: str) -> Markup | None:
    where = f"{file}: markups[{index}]"
    if not isinstance(item, dict) or not isinstance(item.get("type"), str):
        raise InvalidInput(f"{where} has no 'type'")
    kind = "curve" if item["type"] in CURVE_TYPES else "landmarks" if item["type"] in POINT_TYPES else None
    if kind is None:
        return None  # planes, angles, ROIs: nothing a curve can be made of
    system = item.get("coordinateSystem", "LPS")
    if system not in TO_LPS:
        raise InvalidInput(f"{where}: coordinateSystem '{system}' is neither LPS nor RAS")
    points = item.get("controlPoints", [])
    if not isinstance(points, list):
        raise InvalidInput(f"{where}: 'controlPoints' is not a list")
    labels, positions = [], []
    for n, point in enumerate(points):
        if isinstance(point, dict) and point.get("positionStatus", "defined") != "defined":
            continue  # a point placed in Slicer's preview, or left unset
        label = str(point.get("label", "")) if isinstance(point, dict) else ""
        labels.append(label or str(n + 1))
        positions.append(
            _position(point.get("position") if isinstance(point, dict) else None, f"{where} point {n + 1}")
        )
    name = str(item.get("name", "")) or f"{item['type']} {index + 1}"
    return Markup(kind, name, labels, np.array(positions).reshape(-1, 3) * TO_LPS[system], file)


def _position(value: Any, where: str) -> list[float]:
    if not isinstance(value, list) or len(value) != 3:
        raise InvalidInput(f"{where}: 'position' is not [x, y, z]")
    try:
        xyz = [float(v) for v in value]
    except (TypeError, ValueError):
        raise InvalidInput(f"{where}: 'position' {value} is not three numbers") from None
    if not all(math.isfinite(v) for v in xyz):
        raise InvalidInput(f"{where}: 'position' {value} is not finite")
    return xyz


def _read_fcsv(text: str, file: str) -> Markup:
    system, columns = "LPS", FCSV_COLUMNS_DEFAULT
    rows = []
    for number, line in enumerate(text.splitlines(), start=1):
        if line.startswith("#"):
            key, _, value = line[1:].partition("=")
            if key.strip() == "CoordinateSystem":
                system = _fcsv_system(value.strip(), file)
            elif key.strip() == "columns":
                columns = [c.strip() for c in value.split(",")]
        elif line.strip():
            rows.append((number, line))
    if "x" not in columns or "y" not in columns or "z" not in columns:
        raise InvalidInput(f"{file}: the .fcsv columns name no x, y and z")
    labels: list[str] = []
    positions = []
    for number, line in rows:
        values = dict(zip(columns, next(csv.reader(io.StringIO(line))), strict=False))
        point = _position([values.get(axis) for axis in "xyz"], f"{file} line {number}")
        labels.append(values.get("label") or values.get("id") or str(len(labels) + 1))
        positions.append(point)
    return Markup("landmarks", "landmarks", labels, np.array(positions).reshape(-1, 3) * TO_LPS[system], file)


FCSV_COLUMNS_DEFAULT = "id,x,y,z,ow,ox,oy,oz,vis,sel,lock,label,desc,associatedNodeID".split(",")


def _fcsv_system(value: str, file: str) -> str:
    if value not in FCSV_SYSTEMS:
        raise InvalidInput(f"{file}: CoordinateSystem '{value}' is none of LPS, RAS, 0 (RAS), 1 (LPS)")
    return FCSV_SYSTEMS[value]


def pair_markups(source: list[Markup], target: list[Markup]) -> MarkupPairs:
    """Curves of the same name pair; when no name matches, the curves pair in order (then both files need as many);
    landmarks pair by label (a label twice in one file is refused)."""
    curves_M = [m for m in source if m.kind == "curve"]
    curves_N = [m for m in target if m.kind == "curve"]
    by_name = {m.name: m for m in curves_N}
    named = [(m.name, m, by_name[m.name]) for m in curves_M if m.name in by_name]
    unpaired = []
    if named:
        paired = {name for name, _, _ in named}
        unpaired += [f"curve '{m.name}'" for m in curves_M + curves_N if m.name not in paired]
    elif len(curves_M) != len(curves_N):
        raise InvalidInput(
            f"the source file has {len(curves_M)} curves and the target file {len(curves_N)}, with no name in common: "
            "curves pair by name, or in order when both files have as many"
        )
    else:
        named = [(m.name, m, n) for m, n in zip(curves_M, curves_N, strict=True)]
    points_M, points_N = _landmarks(source), _landmarks(target)
    landmarks = [(label, point, points_N[label]) for label, point in points_M.items() if label in points_N]
    unpaired += [f"landmark '{label}'" for label in (points_M.keys() ^ points_N.keys())]
    files = (source[0].file if source else "", target[0].file if target else "")
    return MarkupPairs(named, landmarks, sorted(unpaired), files)


def _landmarks(markups: list[Markup]) -> dict[str, np.ndarray]:
    labels = [(label, m.file) for m in markups if m.kind == "landmarks" for label in m.labels]
    twice = [label for label, count in Counter(label for label, _ in labels).items() if count > 1]
    if twice:
        file = next(f for label, f in labels if label == twice[0])
        raise InvalidInput(f"{file}: landmark label '{twice[0]}' is given twice; landmarks pair by label")
    return {
        label: point for m in markups if m.kind == "landmarks" for label, point in zip(m.labels, m.points, strict=True)
    }
