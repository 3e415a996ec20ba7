"""How the UI turns a shape to show it by default (``axes.js``): the up axis of real meshes, TOSCA (z up), FAUST and
pyFM's cat and lion (y up), and the side the view shows given the curves. The module runs in Node."""

from __future__ import annotations

import json
import subprocess

import numpy as np
from support.paths import REPO

from curvefm.geometry import display_mesh, load_mesh
from curvefm.service.demo import demo_shapes

AXES_JS = REPO / "src" / "curvefm" / "service" / "static" / "axes.js"
RUN = f"""
import {{ readFileSync }} from "node:fs";
import {{ chooseAxes, curvesMostlyBehind }} from {json.dumps(AXES_JS.as_uri())};
const {{ meshes, views }} = JSON.parse(readFileSync(0, "utf8"));
console.log(JSON.stringify({{
  axes: meshes.map(({{ vertices, faces }}) => chooseAxes(Float32Array.from(vertices), Uint32Array.from(faces), "auto")),
  behind: views.map(({{ paths, axis, middle }}) =>
    curvesMostlyBehind(paths.map((p) => Float32Array.from(p)), axis, middle)),
}}));
"""
Y_UP = ["nonisometric/pyfm_cat_lion/cat-00.off", "nonisometric/pyfm_cat_lion/lion-00.off", "faust/tr_reg_000.off"]
Z_UP = [f"tosca/{name}.off" for name in ("cat0", "cat1", "dog2", "horse0", "wolf1", "centaur1", "gorilla5", "michael0")]


def run(node: str, meshes: list = (), views: list = ()) -> dict:
    payload = {
        "meshes": [{"vertices": v.ravel().tolist(), "faces": f.ravel().tolist()} for v, f in meshes],
        "views": list(views),
    }
    done = subprocess.run(
        [node, "--input-type=module", "-e", RUN], input=json.dumps(payload), capture_output=True, text=True
    )
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout)


def test_the_up_axis_stands_animals_and_people_on_their_feet(node, shared_data):
    meshes = [load_mesh(shared_data / name) for name in Y_UP + Z_UP]
    copy = display_mesh(meshes[0], 2000)  # a big shape is turned by its display copy
    shapes = [(m.vertices, m.faces) for m in meshes] + [(meshes[0].vertices[copy.vertex_ids], copy.faces)]
    demo = demo_shapes()[0]  # z up, its legs along -z
    ups = [axes["up"] for axes in run(node, [*shapes, (demo.vertices, demo.faces)])["axes"]]
    names = Y_UP + Z_UP + ["cat-00 display copy", "demo"]
    assert dict(zip(names, ups, strict=True)) == dict(
        zip(names, ["y"] * len(Y_UP) + ["z"] * len(Z_UP) + ["y", "z"], strict=True)
    )


def path_at(depth: float) -> list[float]:
    """A curve of three points at ``depth`` along y."""
    return np.array([[0.0, depth, 0.0], [0.5, depth, 0.2], [1.0, depth, 0.4]]).ravel().tolist()


def test_one_curve_on_the_back_does_not_turn_the_view(node):
    long_back_curve = np.tile(path_at(-1), 50)  # many vertices, one curve: it counts once
    views = [
        {"paths": [path_at(1), path_at(1), long_back_curve.tolist()], "axis": "y", "middle": 0},
        {"paths": [path_at(-1)], "axis": "y", "middle": 0},  # a lone curve behind: stays at the front
        {"paths": [path_at(-1), path_at(-1), path_at(1)], "axis": "y", "middle": 0},  # two of three: not enough
        {"paths": [path_at(-1), path_at(-1), path_at(-1), path_at(1)], "axis": "y", "middle": 0},
        {"paths": [path_at(1)] * 3, "axis": "y", "middle": 2},  # behind a middle further out
    ]
    assert run(node, views=views)["behind"] == [False, False, False, True, True]
