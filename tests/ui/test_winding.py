"""The UI's test of how a mesh's faces are wound (``outwardWinding`` in the UI's ``mesh.js``), which decides
whether the viewports draw one side of the surface or both. The module runs in Node on real meshes, validated
by the library as the service validates an upload."""

from __future__ import annotations

import json
import subprocess

import numpy as np
from support.paths import REPO

from curvefm.geometry import display_mesh, load_mesh

MESH_JS = REPO / "src" / "curvefm" / "service" / "static" / "mesh.js"
RUN = f"""
import {{ readFileSync }} from "node:fs";
import {{ outwardWinding }} from {json.dumps(MESH_JS.as_uri())};
const meshes = JSON.parse(readFileSync(0, "utf8"));
console.log(JSON.stringify(meshes.map(({{ vertices, faces }}) =>
  outwardWinding(Float32Array.from(vertices), Uint32Array.from(faces), vertices.length / 3))));
"""


def windings(node: str, meshes: list[tuple[np.ndarray, np.ndarray]]) -> list[int]:
    payload = [{"vertices": v.ravel().tolist(), "faces": f.ravel().tolist()} for v, f in meshes]
    done = subprocess.run(
        [node, "--input-type=module", "-e", RUN], input=json.dumps(payload), capture_output=True, text=True
    )
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout)


def tosca(shared_data, name: str):
    mesh = load_mesh(shared_data / "tosca" / f"{name}.off")
    return mesh.vertices, mesh.faces


def inside_out(mesh):
    vertices, faces = mesh
    return vertices, faces[:, ::-1]


def cut_open(mesh, share: float):
    """Without the faces whose first vertex lies in the top ``share`` of the height: a shape with a wide opening."""
    vertices, faces = mesh
    height = vertices[faces[:, 0], 2]
    return vertices, faces[height < np.quantile(height, 1 - share)]


def with_one_face_flipped(mesh):
    vertices, faces = mesh
    faces = faces.copy()
    faces[0] = faces[0, ::-1]
    return vertices, faces


def test_closed_shapes_and_shapes_with_small_holes_are_seen_from_one_side(node, shared_data):
    horse, cat = tosca(shared_data, "horse0"), tosca(shared_data, "cat0")  # closed; holes of 0.09% of its area
    assert windings(node, [horse, inside_out(horse), cat, inside_out(cat)]) == [1, -1, 1, -1]


def test_a_display_copy_of_a_closed_scan_is_seen_from_one_side(node, shared_data):
    """Else drawing it coarse saves nothing: both sides of every face would be drawn (FAUST, 6,890 -> ~3,000)."""
    faust = load_mesh(shared_data / "faust" / "tr_reg_000.off")
    copy = display_mesh(faust, 3000)
    assert windings(node, [(faust.vertices[copy.vertex_ids], copy.faces)]) == [1]


def test_open_inconsistent_or_mixed_shapes_are_seen_from_both_sides(node, shared_data):
    horse, wolf = tosca(shared_data, "horse0"), tosca(shared_data, "wolf0")
    wolf_beside_horse = np.vstack([horse[0], wolf[0] + [1000, 0, 0]]), np.vstack([horse[1], wolf[1] + len(horse[0])])
    inside_out_wolf = np.vstack([horse[1], wolf[1][:, ::-1] + len(horse[0])])
    cases = [
        cut_open(horse, 0.3),  # a wide opening: its inside shows
        with_one_face_flipped(horse),
        tosca(shared_data, "david0"),  # edges run twice the same way
        (wolf_beside_horse[0], inside_out_wolf),  # two parts wound opposite ways
    ]
    assert windings(node, [wolf_beside_horse, *cases]) == [1, 0, 0, 0, 0]
