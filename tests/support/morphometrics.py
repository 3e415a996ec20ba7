"""Readers of the morphometrics formats written here from their specifications, independently of curvefm's writers
(used by the tests of ``curvefm export`` and of ``GET /sessions/{id}/exports/...``), and Slicer markups files
written as Slicer writes them (for the imports)."""

from __future__ import annotations

import csv
import io
import json

import jsonschema
import numpy as np

# Slicer's markups schema v1.0.3 (Modules/Loadable/Markups/Resources/Schema), its required fields and the types of
# the fields curvefm writes, restated here: the published file is not vendored and tests do not reach the network.
MARKUPS_SCHEMA = {
    "type": "object",
    "required": ["@schema", "markups"],
    "properties": {
        "@schema": {"type": "string", "pattern": r"markups-schema-v1\.0\.3\.json#?$"},
        "markups": {
            "type": "array",
            "items": {
                "type": "object",
                "required": ["type"],
                "properties": {
                    "type": {"enum": ["Fiducial", "Line", "Angle", "Curve", "ClosedCurve", "Plane", "ROI"]},
                    "name": {"type": "string"},
                    "coordinateSystem": {"enum": ["LPS", "RAS"]},
                    "locked": {"type": "boolean"},
                    "labelFormat": {"type": "string"},
                    "controlPoints": {
                        "type": "array",
                        "items": {
                            "type": "object",
                            "properties": {
                                "id": {"type": "string"},
                                "label": {"type": "string"},
                                "description": {"type": "string"},
                                "associatedNodeID": {"type": "string"},
                                "position": {
                                    "type": "array",
                                    "items": {"type": "number"},
                                    "minItems": 3,
                                    "maxItems": 3,
                                },
                                "orientation": {
                                    "type": "array",
                                    "items": {"type": "number"},
                                    "minItems": 9,
                                    "maxItems": 9,
                                },
                                "selected": {"type": "boolean"},
                                "locked": {"type": "boolean"},
                                "visibility": {"type": "boolean"},
                                "positionStatus": {"enum": ["undefined", "preview", "defined"]},
                            },
                        },
                    },
                    "measurements": {"type": "array"},
                },
            },
        },
    },
}


def read_mrk(text: str) -> list[dict]:
    """The markups of a ``.mrk.json``, validated: ``{"type", "name", "system", "labels", "points"}`` each."""
    document = json.loads(text)
    jsonschema.validate(document, MARKUPS_SCHEMA)
    return [
        {
            "type": m["type"],
            "name": m.get("name", ""),
            "system": m.get("coordinateSystem", "LPS"),
            "labels": [p["label"] for p in m["controlPoints"]],
            "points": np.array([p["position"] for p in m["controlPoints"]], dtype=float).reshape(-1, 3),
        }
        for m in document["markups"]
    ]


def read_fcsv(text: str) -> tuple[dict[str, str], list[str], np.ndarray]:
    """A ``.fcsv``: its ``# key = value`` header lines, the labels and the points (columns as its header names)."""
    header, rows = {}, []
    for line in text.splitlines():
        if line.startswith("#"):
            key, _, value = line[1:].partition("=")
            header[key.strip()] = value.strip()
        elif line:
            rows.append(line)
    columns = header["columns"].split(",")
    records = [dict(zip(columns, row, strict=True)) for row in csv.reader(rows)]
    points = np.array([[float(r[axis]) for axis in "xyz"] for r in records]).reshape(-1, 3)
    return header, [r["label"] for r in records], points


def read_tps(text: str) -> list[tuple[str, np.ndarray]]:
    """The specimens of a TPS file: ``LM3=n`` (or ``LM=n``), n coordinate lines, then ``ID=`` among other
    ``KEY=value`` lines; ``(id, points)`` each."""
    specimens: list[tuple[str, np.ndarray]] = []
    lines = [line.strip() for line in text.splitlines() if line.strip()]
    at = 0
    while at < len(lines):
        key, _, value = lines[at].partition("=")
        assert key.upper() in ("LM3", "LM"), f"a specimen starts with LM3= or LM=, not {lines[at]!r}"
        count = int(value)
        points = np.array([[float(v) for v in line.split()] for line in lines[at + 1 : at + 1 + count]])
        at += 1 + count
        name = ""
        while at < len(lines) and not lines[at].upper().startswith(("LM3=", "LM=")):
            key, _, value = lines[at].partition("=")
            name = value if key.upper() == "ID" else name
            at += 1
        specimens.append((name, points.reshape(count, -1)))
    return specimens


def read_morphologika(text: str) -> tuple[list[str], np.ndarray]:
    """The names and the ``(individuals, landmarks, dimensions)`` raw points of a morphologika file."""
    sections: dict[str, list[str]] = {}
    current = None
    for line in text.splitlines():
        line = line.strip()
        if line.startswith("[") and line.endswith("]"):
            current = sections.setdefault(line[1:-1].lower(), [])
        elif line and current is not None:
            current.append(line)
    individuals, landmarks = int(sections["individuals"][0]), int(sections["landmarks"][0])
    dimensions = int(sections["dimensions"][0])
    rows = [line.split() for line in sections["rawpoints"] if not line.startswith("'")]
    points = np.array(rows, dtype=float).reshape(individuals, landmarks, dimensions)
    return sections["names"], points


def read_curveslide(text: str) -> list[tuple[int, int, int]]:
    return [(int(r["before"]), int(r["slider"]), int(r["after"])) for r in csv.DictReader(io.StringIO(text))]


def mrk_file(markups: list[tuple[str, str, list[str], np.ndarray]], system: str = "LPS") -> bytes:
    """A ``.mrk.json`` as Slicer writes it: ``(type, name, labels, points)`` per markup, positions in ``system``."""
    flip = np.array([-1.0, -1.0, 1.0]) if system == "RAS" else np.ones(3)
    return json.dumps(
        {
            "@schema": "https://raw.githubusercontent.com/slicer/slicer/master/Modules/Loadable/Markups/Resources/"
            "Schema/markups-schema-v1.0.3.json#",
            "markups": [
                {
                    "type": kind,
                    "name": name,
                    "coordinateSystem": system,
                    "coordinateUnits": "mm",
                    "controlPoints": [
                        {
                            "id": str(i + 1),
                            "label": label,
                            "position": (point * flip).tolist(),
                            "positionStatus": "defined",
                        }
                        for i, (label, point) in enumerate(zip(labels, points, strict=True))
                    ],
                }
                for kind, name, labels, points in markups
            ],
        }
    ).encode()


def fcsv_file(labels: list[str], points: np.ndarray, system: str = "LPS") -> bytes:
    """A ``.fcsv`` as Slicer 4.11+ writes it."""
    flip = np.array([-1.0, -1.0, 1.0]) if system == "RAS" else np.ones(3)
    lines = [
        "# Markups fiducial file version = 4.11",
        f"# CoordinateSystem = {system}",
        "# columns = id,x,y,z,ow,ox,oy,oz,vis,sel,lock,label,desc,associatedNodeID",
    ]
    for i, (label, point) in enumerate(zip(labels, points * flip, strict=True)):
        x, y, z = (repr(float(v)) for v in point)
        lines.append(f"{i + 1},{x},{y},{z},0,0,0,1,1,1,0,{label},,")
    return ("\n".join(lines) + "\n").encode()
