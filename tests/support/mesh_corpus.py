"""The malformed-mesh corpus, made in code: ``corpus_dir()`` writes its files (``meshes/`` and a few side files)
into a temporary folder once per test process, and ``MANIFEST`` says what loading each mesh must give.

Every file is made here from a few bytes of text or packed numbers; nothing is copied from a data set, and
nothing is committed: the tests build the corpus when they run.

Each case is ``(file name, content, expected)``, where ``expected`` is ``reject(substring, kind)``: loading
raises a CurvefmError of that kind whose message contains the substring, or ``accept(vertices, faces)``:
the mesh loads with that many vertices and faces. ``huge`` marks the files whose header declares far more than
they hold: loading them must cost memory proportional to the file, not to the header.
"""

from __future__ import annotations

import atexit
import base64
import json
import random
import shutil
import struct
import tempfile
from functools import cache
from pathlib import Path

TRI_V = [(0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (0.0, 1.0, 0.0)]
QUAD_V = [*TRI_V, (1.0, 1.0, 0.0)]
SOUP_V = [*TRI_V, (5.0, 5.0, 5.0), (6.0, 5.0, 5.0), (5.0, 6.0, 5.0)]


def reject(message: str, kind: str = "invalid", huge: bool = False) -> dict:
    return {"expect": "reject", "message": message, "kind": kind, "huge": huge}


def accept(vertices: int, faces: int, texture: str | None = None, uv: bool = False) -> dict:
    return {"expect": "accept", "vertices": vertices, "faces": faces, "texture": texture, "uv": uv}


def junk(size: int = 512, seed: int = 0) -> bytes:
    return random.Random(seed).randbytes(size)


# ----------------------------------------------------------------------------------------------------------
# Builders, one per format


def off(vertices=TRI_V, faces=((0, 1, 2),), counts: str | None = None, tail: str = "") -> bytes:
    counts = counts or f"{len(vertices)} {len(faces)} 0"
    rows = [" ".join(map(str, v)) for v in vertices] + [" ".join(map(str, [len(f), *f])) for f in faces]
    return ("OFF\n" + counts + "\n" + "\n".join(rows) + "\n" + tail).encode()


def obj(*lines: str) -> bytes:
    return ("\n".join(lines) + "\n").encode()


OBJ_TRI = ("v 0 0 0", "v 1 0 0", "v 0 1 0")


def ply_ascii(vertices=TRI_V, faces=((0, 1, 2),), n_vertices=None, n_faces=None, header="", tail="") -> bytes:
    head = (
        f"ply\nformat ascii 1.0\n{header}element vertex {len(vertices) if n_vertices is None else n_vertices}\n"
        "property float x\nproperty float y\nproperty float z\n"
        f"element face {len(faces) if n_faces is None else n_faces}\nproperty list uchar int vertex_indices\n"
        "end_header\n"
    )
    rows = [" ".join(map(str, v)) for v in vertices] + [" ".join(map(str, [len(f), *f])) for f in faces]
    return (head + "".join(r + "\n" for r in rows) + tail).encode()


def ply_binary(vertices=TRI_V, faces=((0, 1, 2),), n_vertices=None, n_faces=None, endian="<", count="I") -> bytes:
    fmt = {"<": "binary_little_endian", ">": "binary_big_endian"}[endian]
    head = (
        f"ply\nformat {fmt} 1.0\nelement vertex {len(vertices) if n_vertices is None else n_vertices}\n"
        "property float x\nproperty float y\nproperty float z\n"
        f"element face {len(faces) if n_faces is None else n_faces}\n"
        f"property list {'uchar' if count == 'B' else 'uint'} int vertex_indices\nend_header\n"
    ).encode()
    body = b"".join(struct.pack(endian + "3f", *v) for v in vertices)
    body += b"".join(struct.pack(f"{endian}{count}{len(f)}i", len(f), *f) for f in faces)
    return head + body


def stl_binary(triangles, count: int | None = None, header: bytes = b"binary stl".ljust(80)) -> bytes:
    body = b"".join(struct.pack("<12fH", 0, 0, 1, *[c for p in t for c in p], 0) for t in triangles)
    return header + struct.pack("<I", len(triangles) if count is None else count) + body


def stl_ascii(triangles, tail: str = "") -> bytes:
    facets = "".join(
        "facet normal 0 0 1\nouter loop\n" + "".join(f"vertex {x} {y} {z}\n" for x, y, z in t) + "endloop\nendfacet\n"
        for t in triangles
    )
    return f"solid corpus\n{facets}endsolid corpus\n{tail}".encode()


def gltf_document(count: int = 3, uri: str | None = None, images: list | None = None, positions=TRI_V) -> dict:
    """A one-triangle glTF: positions then uint32 indices in one buffer, embedded as a data: URI."""
    data = struct.pack("<9f", *[c for p in positions for c in p]) + struct.pack("<3I", 0, 1, 2)
    document = {
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1, "mode": 4}]}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": count, "type": "VEC3"},
            {"bufferView": 1, "componentType": 5125, "count": 3, "type": "SCALAR"},
        ],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 36},
            {"buffer": 0, "byteOffset": 36, "byteLength": 12},
        ],
        "buffers": [{"byteLength": 48, "uri": uri or DATA_URI + base64.b64encode(data).decode()}],
    }
    if images is not None:
        document["images"] = images
    return document


def glb(document: dict | None = None, binary: bool = True) -> bytes:
    """A GLB: the document as JSON chunk, the buffer as binary chunk (the buffer then has no uri)."""
    document = document or gltf_document()
    payload = base64.b64decode(document["buffers"][0]["uri"].split(",", 1)[1]) if binary else b""
    if binary:
        document = {**document, "buffers": [{"byteLength": len(payload)}]}
    text = json.dumps(document).encode()
    text += b" " * (-len(text) % 4)
    chunks = struct.pack("<I4s", len(text), b"JSON") + text
    if binary:
        chunks += struct.pack("<I4s", len(payload), b"BIN\x00") + payload
    return struct.pack("<4sII", b"glTF", 2, 12 + len(chunks)) + chunks


def gltf(document: dict | None = None) -> bytes:
    return json.dumps(document or gltf_document()).encode()


TRIANGLE = [TRI_V]
DATA_URI = "data:application/octet-stream;base64,"
SOUP = [TRI_V, SOUP_V[3:]]


# ----------------------------------------------------------------------------------------------------------
# The cases

CASES = [
    # valid controls: every reader's accepting path
    ("ok.off", off(), accept(3, 1)),
    ("ok.obj", obj(*OBJ_TRI, "f 1 2 3"), accept(3, 1)),
    ("ok_ascii.ply", ply_ascii(), accept(3, 1)),
    ("ok_binary.ply", ply_binary(), accept(3, 1)),
    ("ok_binary_big_endian.ply", ply_binary(endian=">", count="B"), accept(3, 1)),
    ("ok_binary_mixed_polygons.ply", ply_binary(QUAD_V, [(0, 1, 2), (1, 3, 2, 0)]), accept(4, 3)),
    ("ok.stl", stl_binary(TRIANGLE), accept(3, 1)),
    ("ok_binary_starting_with_solid.stl", stl_binary(TRIANGLE, header=b"solid but binary".ljust(80)), accept(3, 1)),
    ("ok_ascii.stl", stl_ascii(TRIANGLE), accept(3, 1)),
    ("ok.gltf", gltf(), accept(3, 1)),
    ("ok.glb", glb(), accept(3, 1)),
    ("quads.off", off(QUAD_V, [(0, 1, 3, 2)]), accept(4, 2)),
    ("trailing_comment.off", off(tail="# a comment after the faces\n\n"), accept(3, 1)),
    ("comments_and_crlf.off", b"# by hand\r\nOFF\r\n3 1 0\r\n0 0 0\r\n1 0 0 # x\r\n0 1 0\r\n3 0 1 2\r\n", accept(3, 1)),
    # empty files
    ("empty.off", b"", reject("the file is empty")),
    ("empty.obj", b"", reject("the file is empty")),
    ("empty.ply", b"", reject("the file is empty")),
    ("empty.stl", b"", reject("the file is empty")),
    ("empty.glb", b"", reject("the file is empty")),
    ("empty.gltf", b"", reject("the file is empty")),
    ("only_comments.off", b"# nothing here\n", reject("not an OFF file")),
    ("only_header.ply", b"ply\nformat ascii 1.0\nend_header\n", reject("no 'vertex' element")),
    ("solid_only.stl", b"solid nothing\nendsolid nothing\n", reject("no faces")),
    # binary junk under each extension
    ("junk.off", junk(seed=1), reject("not an OFF file")),
    ("junk.obj", junk(seed=2), reject("could not read any vertices")),
    ("junk.ply", junk(seed=3), reject("not a PLY file")),
    ("junk.stl", junk(seed=4), reject("not an STL file")),
    ("junk.glb", junk(seed=5), reject("not a GLB file")),
    ("junk.gltf", junk(seed=6), reject("JSON is invalid")),
    ("junk_after_ply_magic.ply", b"ply\n" + junk(seed=7), reject("no 'end_header'")),
    ("junk_after_solid.stl", b"solid x\n" + junk(seed=8), reject("ASCII STL")),
    # NaN and inf coordinates
    ("nan.off", off([(0, 0, 0), (1, "nan", 0), (0, 1, 0)]), reject("non-finite")),
    ("inf.off", off([(0, 0, 0), (1, "1e999", 0), (0, 1, 0)]), reject("non-finite")),
    ("inf.obj", obj("v 0 0 0", "v inf 0 0", "v 0 1 0", "f 1 2 3"), reject("non-finite")),
    ("nan_ascii.ply", ply_ascii([(0, 0, 0), (1, 0, "nan"), (0, 1, 0)]), reject("non-finite")),
    ("nan_binary.ply", ply_binary([(0, 0, 0), (1, 0, float("nan")), (0, 1, 0)]), reject("non-finite")),
    ("nan.stl", stl_binary([[(0, 0, 0), (float("nan"), 0, 0), (0, 1, 0)]]), reject("non-finite")),
    ("inf.gltf", gltf(gltf_document(positions=[(0, 0, 0), (float("inf"), 0, 0), (0, 1, 0)])), reject("non-finite")),
    # negative and out-of-range indices
    ("negative_index.off", off(faces=[(0, 1, -1)]), reject("refers to vertex -1")),
    ("negative_index_relative.obj", obj(*OBJ_TRI, "f -3 -2 -1"), accept(3, 1)),
    ("negative_index_before_first.obj", obj(*OBJ_TRI, "f -4 -2 -1"), reject("reaches before the first")),
    ("negative_index_ascii.ply", ply_ascii(faces=[(0, 1, -5)]), reject("refers to vertex -5")),
    ("negative_index_binary.ply", ply_binary(faces=[(0, 1, -1)]), reject("refers to vertex -1")),
    ("out_of_range.off", off(faces=[(0, 1, 7)]), reject("refers to vertex 7")),
    ("out_of_range.obj", obj(*OBJ_TRI, "f 1 2 8"), reject("refers to vertex 8")),
    ("out_of_range_ascii.ply", ply_ascii(faces=[(0, 1, 7)]), reject("refers to vertex 7")),
    ("out_of_range_binary.ply", ply_binary(faces=[(0, 1, 3)]), reject("refers to vertex 3")),
    ("zero_index.obj", obj(*OBJ_TRI, "f 0 1 2"), reject("OBJ ids start at 1")),
    ("out_of_range_vt.obj", obj(*OBJ_TRI, "vt 0 0", "f 1/1 2/1 3/5"), reject("texture coordinate 5")),
    ("index_beyond_int64.obj", obj(*OBJ_TRI, "f 1 2 99999999999999999999"), reject("too large")),
    ("index_beyond_int64.off", off(faces=[(0, 1, 99999999999999999999)]), reject("too large")),
    ("index_not_a_number.off", off(faces=[(0, 1, "two")]), reject("expected an integer, found 'two'")),
    # faces with fewer than three corners
    ("two_corners.off", off(faces=[(0, 1)]), reject("face 0 has 2 corners")),
    ("zero_corners.off", off(faces=[()]), reject("face 0 has 0 corners")),
    ("negative_corners.off", b"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n-1 0 1 2\n", reject("fewer vertex ids")),
    (
        "too_many_corners_declared.off",
        off(faces=[(0, 1, 2)], tail="").replace(b"3 0 1 2", b"9 0 1 2"),
        reject("fewer vertex ids than it declares"),
    ),
    ("two_corners.obj", obj(*OBJ_TRI, "f 1 2"), reject("has 2 corners")),
    ("two_corners_ascii.ply", ply_ascii(faces=[(0, 1)]), reject("face 0 has 2 corners")),
    ("two_corners_binary.ply", ply_binary(faces=[(0, 1)]), reject("face 0 has 2 corners")),
    ("one_corner_binary_mixed.ply", ply_binary(faces=[(0, 1, 2), (0,)]), reject("face 1 has 1 corners")),
    ("facet_with_four_vertices.stl", stl_ascii([QUAD_V]), reject("STL facets are triangles")),
    # no faces
    ("no_faces.off", off(faces=[]), reject("no faces")),
    ("points_only.obj", obj(*OBJ_TRI), reject("no faces")),
    ("lines_only.obj", obj(*OBJ_TRI, "l 1 2 3"), reject("no faces")),
    (
        "no_face_element.ply",
        b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
        b"property float z\nend_header\n0 0 0\n",
        reject("no faces"),
    ),
    ("zero_faces.ply", ply_ascii(faces=[]), reject("no faces")),
    ("no_faces.stl", stl_binary([]), reject("no faces")),
    ("degenerate_only.off", off([(0, 0, 0), (1, 0, 0), (2, 0, 0)]), reject("degenerate")),
    # header counts far beyond the file
    ("huge_vertex_count.off", off(counts="100000000 1 0"), reject("the file is shorter", huge=True)),
    ("huge_face_count.off", off(counts="3 2000000000 0"), reject("the file is shorter", huge=True)),
    ("huge_vertex_count_100M.ply", ply_ascii(n_vertices=100_000_000), reject("the file is shorter", huge=True)),
    ("huge_vertex_count_2G.ply", ply_ascii(n_vertices=2_000_000_000), reject("the file is shorter", huge=True)),
    ("huge_face_count.ply", ply_ascii(n_faces=2_000_000_000), reject("the file is shorter", huge=True)),
    ("huge_vertex_count_binary.ply", ply_binary(n_vertices=2_000_000_000), reject("the file is shorter", huge=True)),
    (
        "huge_list_length_binary.ply",
        ply_binary(faces=[(0, 1, 2)]).replace(
            struct.pack("<I3i", 3, 0, 1, 2), struct.pack("<I3i", 4_000_000_000, 0, 1, 2)
        ),
        reject("truncated", huge=True),
    ),
    ("huge_triangle_count.stl", stl_binary(TRIANGLE, count=2_000_000_000), reject("not an STL file", huge=True)),
    # bytes 80-84 of this ASCII STL read as a binary count of 2,021,161,080 triangles: it must be read as text
    ("huge_count_in_ascii_stl_header.stl", stl_ascii(TRIANGLE).replace(b"corpus", b"x" * 90), accept(3, 1)),
    ("huge_position_count.gltf", gltf(gltf_document(count=1_000_000_000)), reject("the file is shorter", huge=True)),
    (
        "huge_accessor_without_buffer.gltf",
        gltf(
            {
                **gltf_document(),
                "accessors": [
                    *gltf_document()["accessors"],
                    {"componentType": 5126, "count": 8_000_000_000, "type": "MAT4"},
                ],
            }
        ),
        reject("the file is shorter", huge=True),
    ),
    ("accessor_count_infinite.gltf", gltf(gltf_document(count=float("inf"))), reject("glTF structure")),
    (
        "huge_element_count.ply",
        ply_ascii(header="element edge 4000000000\nproperty int a\n"),
        reject("the file is shorter", huge=True),
    ),
    # an OFF, OBJ, PLY, STL or glTF under another format's extension
    ("off_named.ply", off(), reject("not a PLY file")),
    ("off_named.obj", off(), reject("could not read any vertices")),
    ("off_named.stl", off(), reject("not an STL file")),
    ("obj_named.off", obj(*OBJ_TRI, "f 1 2 3"), reject("not an OFF file")),
    ("ply_named.stl", ply_ascii(), reject("not an STL file")),
    ("ply_named.off", ply_ascii(), reject("not an OFF file")),
    ("stl_named.ply", stl_binary(TRIANGLE), reject("not a PLY file")),
    ("ascii_stl_named.obj", stl_ascii(TRIANGLE), reject("could not read any vertices")),
    ("glb_named.gltf", glb(), reject("JSON is invalid")),
    ("gltf_named.glb", gltf(), reject("not a GLB file")),
    ("obj_named.gltf", obj(*OBJ_TRI, "f 1 2 3"), reject("JSON is invalid")),
    # bytes that are not UTF-8
    ("latin1_in_vertex.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 caf\xe9\nf 1 2 3\n", reject("not UTF-8")),
    ("latin1_in_comment.obj", b"# caf\xe9 cr\xe9\xe9\n" + obj(*OBJ_TRI, "f 1 2 3"), accept(3, 1)),
    ("latin1_in_vertex.off", off([(0, 0, 0), (1, 0, 0), (0, 1, "x")]).replace(b"1 x", b"1 \xe9"), reject("not UTF-8")),
    ("latin1_in_header.ply", ply_ascii().replace(b"float z", b"float \xe9"), reject("not ASCII text")),
    ("latin1_in_header_comment.ply", ply_ascii(header="comment cafe\n").replace(b"cafe", b"caf\xe9"), accept(3, 1)),
    ("utf16.off", off().decode().encode("utf-16"), reject("not an OFF file")),
    ("utf16.obj", obj(*OBJ_TRI, "f 1 2 3").decode().encode("utf-16"), reject("could not read any vertices")),
    # mtllib and map_Kd: opened only inside the mesh's folder
    ("mtllib_inside.obj", obj("mtllib inside.mtl", *OBJ_TRI, "f 1 2 3"), accept(3, 1, texture="texture.png")),
    ("mtllib_absolute.obj", obj("mtllib /etc/passwd", *OBJ_TRI, "f 1 2 3"), accept(3, 1)),
    ("mtllib_parent.obj", obj("mtllib ../outside.mtl", *OBJ_TRI, "f 1 2 3"), accept(3, 1)),
    ("mtllib_image_outside.obj", obj("mtllib image_outside.mtl", *OBJ_TRI, "f 1 2 3"), accept(3, 1)),
    ("mtllib_name_too_long.obj", obj("mtllib " + "m" * 5000, *OBJ_TRI, "f 1 2 3"), accept(3, 1)),
    ("mtllib_nul_byte.obj", obj("mtllib in\0side.mtl", *OBJ_TRI, "f 1 2 3"), accept(3, 1)),
    ("mtllib_not_utf8.obj", obj(*OBJ_TRI, "f 1 2 3").replace(b"v 0 0 0", b"mtllib \xff.mtl\nv 0 0 0"), accept(3, 1)),
    # glTF naming other files
    ("external_buffer.gltf", gltf(gltf_document(uri="mesh.bin")), reject("refers to another file")),
    ("external_buffer_absolute.gltf", gltf(gltf_document(uri="/etc/passwd")), reject("refers to another file")),
    ("external_buffer_parent.gltf", gltf(gltf_document(uri="../outside.bin")), reject("refers to another file")),
    ("external_buffer.glb", glb(gltf_document(uri="mesh.bin"), binary=False), reject("refers to another file")),
    ("external_image.gltf", gltf(gltf_document(images=[{"uri": "../outside.png"}])), reject("refers to another file")),
    ("deeply_nested.gltf", b"[" * 5000 + b"]" * 5000, reject("JSON is invalid")),
    ("not_an_object.gltf", b"[1, 2, 3]", reject("not an object")),
    ("wrong_structure.gltf", gltf({"asset": {}, "meshes": [{"primitives": 7}]}), reject("glTF structure")),
    # polygon soup (disconnected triangles): accepted, the components are reported
    ("soup.off", off(SOUP_V, [(0, 1, 2), (3, 4, 5)]), accept(6, 2)),
    ("soup.obj", obj(*[f"v {x} {y} {z}" for x, y, z in SOUP_V], "f 1 2 3", "f 4 5 6"), accept(6, 2)),
    ("soup.stl", stl_binary(SOUP), accept(6, 2)),
    # texture coordinates with only u (v = 0), or a mix of one and two values
    ("vt_u_only.obj", obj(*OBJ_TRI, "vt 0.1", "vt 0.2", "vt 0.3", "f 1/1 2/2 3/3"), accept(3, 1, uv=True)),
    ("vt_mixed.obj", obj(*OBJ_TRI, "vt 0.1", "vt 0.2 0.5", "vt 0.3 0.7 0", "f 1/1 2/2 3/3"), accept(3, 1, uv=True)),
    ("vt_empty.obj", obj(*OBJ_TRI, "vt", "f 1/1 2/1 3/1"), reject("needs at least one value")),
    ("vertex_with_two_coordinates.obj", obj("v 0 0", *OBJ_TRI[1:], "f 1 2 3"), reject("needs three coordinates")),
    # content after the declared elements
    ("trailing_junk.off", off(tail="this is not part of the mesh\n"), reject("after the 3 vertices and 1 faces")),
    ("trailing_elements.off", off(tail="0 0 1\n3 0 1 2\n"), reject("remove the trailing content")),
    ("trailing_junk_ascii.ply", ply_ascii(tail="junk\n"), reject("after the elements the header declares")),
    ("trailing_bytes_binary.ply", ply_binary() + junk(64, seed=9), reject("bytes follow the elements")),
    ("trailing_junk.stl", stl_ascii(TRIANGLE, tail="junk\n"), reject("unexpected 'junk'")),
    # truncated files and broken headers
    ("truncated_faces.off", b"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n", reject("the file is shorter (0 face lines)")),
    ("binary_off.off", b"OFF BINARY\n" + junk(64, seed=10), reject("binary OFF is not supported")),
    ("negative_counts.off", off(counts="-3 1 0"), reject("negative counts")),
    ("missing_counts.off", b"OFF\n", reject("numbers of vertices and faces")),
    ("truncated_binary.ply", ply_binary()[:-6], reject("truncated")),
    ("truncated.stl", stl_binary(TRIANGLE)[:-10], reject("not an STL file")),
    ("ply_without_end_header.ply", ply_ascii().replace(b"end_header", b"end_head"), reject("no 'end_header'")),
    ("ply_unknown_type.ply", ply_ascii().replace(b"float x", b"quaternion x"), reject("is not understood")),
    ("ply_without_format.ply", ply_ascii().replace(b"format ascii 1.0\n", b""), reject("no 'format")),
    (
        "ply_property_before_element.ply",
        ply_ascii().replace(b"1.0\n", b"1.0\nproperty int q\n"),
        reject("before any element"),
    ),
    ("ply_without_z.ply", ply_ascii().replace(b"property float z\n", b""), reject("with x, y and z")),
    ("ply_short_vertex_line.ply", ply_ascii().replace(b"\n1.0 0.0 0.0\n", b"\n1.0 0.0\n"), reject("fewer values")),
]


SIDE_FILES = {  # read by the mtllib cases; not meshes, so not in the manifest
    "meshes/inside.mtl": b"newmtl skin\nmap_Kd texture.png\n",
    "meshes/texture.png": b"not really a png: only its existence matters\n",
    "meshes/image_outside.mtl": b"newmtl skin\nmap_Kd ../outside.png\n",
    "outside.mtl": b"newmtl skin\nmap_Kd outside.png\n",
    "outside.png": b"must never be opened\n",
}


def files() -> dict[str, bytes]:
    """Every file of the corpus, by path relative to the corpus folder."""
    names = [name for name, _, _ in CASES]
    assert len(names) == len(set(names)), "duplicate case names"
    return {f"meshes/{name}": content for name, content, _ in CASES} | SIDE_FILES


MANIFEST = {name: expected for name, _, expected in CASES}
"""The expected outcome of loading each file of ``meshes/``, by file name."""


@cache
def corpus_dir() -> Path:
    """The corpus written into a fresh temporary folder (removed when the process exits)."""
    folder = Path(tempfile.mkdtemp(prefix="curvefm-corpus-"))
    atexit.register(shutil.rmtree, folder, ignore_errors=True)
    for relative, content in files().items():
        (folder / relative).parent.mkdir(parents=True, exist_ok=True)
        (folder / relative).write_bytes(content)
    return folder
