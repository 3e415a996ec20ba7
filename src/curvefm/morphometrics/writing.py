"""The files a morphometrics lab reads, written from a :class:`Configuration`.

* ``source.mrk.json`` / ``target.mrk.json``: 3D Slicer markups (schema v1.0.3): a ``Curve`` markup per curve (its
  endpoints and semilandmarks as control points), a ``Fiducial`` markup ``landmarks`` (the endpoints) and one
  ``pseudo-landmarks``; coordinates as the mesh file has them, stated ``LPS``: the frame Slicer gives a mesh it
  loads, so the points sit on it;
* ``source.fcsv`` / ``target.fcsv``: Slicer's older fiducial list, every landmark of the configuration;
* ``landmarks.tps``: both shapes, ``LM3=`` then ``ID=`` (geomorph's ``readland.tps``);
* ``morphologika.txt``: both shapes (``[individuals] [landmarks] [dimensions] [names] [rawpoints]``);
* ``curveslide.csv``: geomorph's sliders, ``before,slider,after`` per semilandmark (1-based landmark numbers).
"""

from __future__ import annotations

import json
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

import numpy as np

from curvefm.morphometrics.configuration import Configuration

MARKUPS_SCHEMA = (
    "https://raw.githubusercontent.com/slicer/slicer/master/Modules/Loadable/Markups/Resources/Schema/"
    "markups-schema-v1.0.3.json#"
)
COORDINATE_SYSTEM = "LPS"
FCSV_VERSION = "4.11"
FCSV_COLUMNS = "id,x,y,z,ow,ox,oy,oz,vis,sel,lock,label,desc,associatedNodeID"
IDENTITY = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]
SIDES = {"source": 0, "target": 1}


def number(value: float) -> str:
    return f"{float(value):.9g}"


def _control_point(index: int, label: str, position: np.ndarray) -> dict[str, Any]:
    return {
        "id": str(index),
        "label": label,
        "description": "",
        "associatedNodeID": "",
        "position": [float(v) for v in position],
        "orientation": IDENTITY,
        "selected": True,
        "locked": False,
        "visibility": True,
        "positionStatus": "defined",
    }


def _markup(kind: str, name: str, config: Configuration, side: int, indices: Iterable[int]) -> dict[str, Any]:
    points = [_control_point(n + 1, config.labels[i], config.points[side][i]) for n, i in enumerate(indices)]
    return {
        "type": kind,
        "name": name,
        "coordinateSystem": COORDINATE_SYSTEM,
        "locked": False,
        "labelFormat": "%N-%d",
        "controlPoints": points,
        "measurements": [],
    }


def markups_json(config: Configuration, side: int) -> str:
    """The Slicer markups of one shape (``side``: 0 source, 1 target)."""
    markups = [_markup("Curve", c.label, config, side, c.control_points) for c in config.curves]
    ends = [i for c in config.curves for i in (c.start, c.end)]
    if ends:
        markups.append(_markup("Fiducial", "landmarks", config, side, ends))
    if config.pseudo:
        markups.append(_markup("Fiducial", "pseudo-landmarks", config, side, config.pseudo))
    return json.dumps({"@schema": MARKUPS_SCHEMA, "markups": markups}, indent=2) + "\n"


def fcsv(config: Configuration, side: int) -> str:
    """Every landmark of one shape as Slicer's fiducial CSV."""
    lines = [
        f"# Markups fiducial file version = {FCSV_VERSION}",
        f"# CoordinateSystem = {COORDINATE_SYSTEM}",
        f"# columns = {FCSV_COLUMNS}",
    ]
    for i, (label, point) in enumerate(zip(config.labels, config.points[side], strict=True)):
        xyz = ",".join(number(v) for v in point)
        lines.append(f"{i + 1},{xyz},0,0,0,1,1,1,0,{label},,")
    return "\n".join(lines) + "\n"


def tps(config: Configuration) -> str:
    """Every shape (both of a session) as TPS: ``LM3=`` with the number of landmarks, one ``x y z`` line each,
    then ``ID=``."""
    lines = []
    for name, points in zip(config.names, config.points, strict=True):
        lines.append(f"LM3={config.size}")
        lines += [" ".join(number(v) for v in point) for point in points]
        lines.append(f"ID={_one_line(name)}")
    return "\n".join(lines) + "\n"


def morphologika(config: Configuration) -> str:
    """Every shape (both of a session) as a morphologika file."""
    names = [_one_line(name).replace(" ", "_") for name in config.names]
    lines = ["[individuals]", str(len(names)), "[landmarks]", str(config.size), "[dimensions]", "3", "[names]", *names]
    lines.append("[rawpoints]")
    for name, points in zip(names, config.points, strict=True):
        lines.append(f"'{name}")
        lines += [" ".join(number(v) for v in point) for point in points]
    return "\n".join(lines) + "\n"


def curveslide_csv(config: Configuration) -> str:
    """geomorph's ``curves`` matrix: each semilandmark slides between its neighbours on its curve (1-based)."""
    rows = ["before,slider,after"]
    for curve in config.curves:
        along = curve.control_points
        rows += [f"{a + 1},{s + 1},{b + 1}" for a, s, b in zip(along, along[1:], along[2:], strict=False)]
    return "\n".join(rows) + "\n"


def pseudo_landmarks_csv(config: Configuration) -> str:
    """Every pseudo-landmark on every shape: ``specimen,label,template_vertex,vertex,x,y,z`` (vertices as file
    ids; ``template_vertex`` the template's vertex it was chosen at, ``vertex`` the one the maps give)."""
    rows = ["specimen,label,template_vertex,vertex,x,y,z"]
    chosen = config.pseudo_origin
    for name, points, vertices in zip(config.names, config.points, config.pseudo_vertices, strict=True):
        specimen = _one_line(name).replace(",", "_")
        for i, (at, vertex) in enumerate(zip(config.pseudo, vertices, strict=True)):
            xyz = ",".join(number(v) for v in points[at])
            rows.append(f"{specimen},{config.labels[at]},{chosen[i]},{vertex},{xyz}")
    return "\n".join(rows) + "\n"


def _one_line(text: str) -> str:
    return " ".join(text.split()) or "shape"


def _sided(write: Callable[[Configuration, int], str], side: str) -> Callable[[Configuration], str]:
    return lambda config: write(config, SIDES[side])


EXPORTS: dict[str, tuple[str, Callable[[Configuration], str]]] = {
    "source.mrk.json": ("application/json", _sided(markups_json, "source")),
    "target.mrk.json": ("application/json", _sided(markups_json, "target")),
    "source.fcsv": ("text/csv", _sided(fcsv, "source")),
    "target.fcsv": ("text/csv", _sided(fcsv, "target")),
    "landmarks.tps": ("text/plain", tps),
    "morphologika.txt": ("text/plain", morphologika),
    "curveslide.csv": ("text/csv", curveslide_csv),
}
"""Each export's file name, media type and writer."""
COLLECTION_EXPORTS: dict[str, tuple[str, Callable[[Configuration], str]]] = {
    "landmarks.tps": ("text/plain", tps),
    "morphologika.txt": ("text/plain", morphologika),
    "curveslide.csv": ("text/csv", curveslide_csv),
    "pseudo_landmarks.csv": ("text/csv", pseudo_landmarks_csv),
}
"""A collection's exports (one specimen per member): file name, media type and writer."""


def write_export(name: str, config: Configuration, folder: Path) -> Path:
    path = folder / name
    path.write_text(EXPORTS[name][1](config))
    return path
