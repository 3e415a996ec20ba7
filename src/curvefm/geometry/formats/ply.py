"""PLY, ASCII and binary, read here; open3d only writes it.

open3d's reader allocates whatever the header declares (a 188-byte file declaring 100,000,000 vertices cost
2.3 GB, 2,000,000,000 a ``bad_alloc``), turns faces of one or two corners into degenerate triangles without a
word, and ear-clips large polygons in quadratic time (a 30,000-corner face in 800 kB: 7 s). So the header is
parsed here, its counts are checked against the file's size and the vertex limit before anything is read,
and the body is read with numpy (binary) or streamed line by line (ASCII: one element per line), keeping the
file's vertex order. What is read: ``x``, ``y``, ``z`` of ``vertex`` and the ``vertex_indices`` (or
``vertex_index``) list of ``face``, polygons triangulated as fans; other properties and elements are skipped.
Content after the declared elements (other than whitespace) is refused.
"""

from __future__ import annotations

import struct
from array import array
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from itertools import islice
from pathlib import Path
from typing import Any, BinaryIO

import numpy as np

from curvefm.errors import InvalidInput
from curvefm.geometry.formats.reading import (
    TextLines,
    check_declared_size,
    counted_ids,
    line_errors,
    numbers,
    shown,
)
from curvefm.geometry.mesh import Mesh
from curvefm.geometry.validation import Polygons, build_mesh, check_vertex_count

TYPES = {  # PLY type names -> struct (and numpy) type codes
    "char": "b",
    "int8": "b",
    "uchar": "B",
    "uint8": "B",
    "short": "h",
    "int16": "h",
    "ushort": "H",
    "uint16": "H",
    "int": "i",
    "int32": "i",
    "uint": "I",
    "uint32": "I",
    "float": "f",
    "float32": "f",
    "double": "d",
    "float64": "d",
}
FORMATS = {"ascii": "", "binary_little_endian": "<", "binary_big_endian": ">"}
FACE_LISTS = ("vertex_indices", "vertex_index")
XYZ = ("x", "y", "z")
MAX_HEADER_BYTES = 1 << 16
MIN_ASCII_VALUE = len(b"0 ")


@dataclass
class _Property:
    name: str
    code: str  # struct type code of the value (of the items, for a list)
    count_code: str | None = None  # struct type code of a list's length; None for a scalar

    def min_bytes(self, ascii: bool) -> int:
        """Fewest bytes one value (a list: its length) takes in the file."""
        return MIN_ASCII_VALUE if ascii else struct.calcsize(self.count_code or self.code)


@dataclass
class _Element:
    name: str
    count: int
    properties: list[_Property] = field(default_factory=list)

    def wanted(self) -> tuple[str, ...]:
        return {"vertex": XYZ, "face": FACE_LISTS}.get(self.name, ())

    def min_bytes(self, ascii: bool) -> int:
        return sum(p.min_bytes(ascii) for p in self.properties)


@dataclass
class _Header:
    endian: str  # "" for ascii, "<" or ">" for binary
    elements: dict[str, _Element]
    lines: int


def read_ply(path: Path, name: str) -> Mesh:
    with open(path, "rb") as f:
        header = _read_header(f, path)
        if header.endian:
            vertices, faces = _binary_body(f.read(), path, header)
        else:
            vertices, faces = _ascii_body(f, path, header)
    return build_mesh(vertices, faces, name=name)


# ----------------------------------------------------------------------------------------------------------
# Header


def _read_header(f: BinaryIO, path: Path) -> _Header:
    if f.readline(16).strip() != b"ply":
        raise InvalidInput(f"{path.name} is not a PLY file: it does not start with 'ply'")
    lines: list[bytes] = []
    total = 0
    while total < MAX_HEADER_BYTES and (line := f.readline(MAX_HEADER_BYTES)):
        total += len(line)
        if line.strip() == b"end_header":
            header = _parse_header(lines, path)
            _check_header(header, path, path.stat().st_size - f.tell())
            return header
        lines.append(line)
    raise InvalidInput(f"{path.name} is not a valid PLY file: no 'end_header' line in its first {total} bytes")


def _parse_header(lines: list[bytes], path: Path) -> _Header:
    endian, elements = None, {}
    for lineno, line in enumerate(lines, 2):
        words = line.split()
        if not words or words[0] in (b"comment", b"obj_info"):
            continue
        if not line.isascii():
            raise InvalidInput(f"{path.name}: PLY header line {lineno} holds bytes that are not ASCII text")
        match [w.decode() for w in words]:
            case ["format", fmt, _] if fmt in FORMATS:
                endian = FORMATS[fmt]
            case ["element", element, count] if count.isdigit() and len(count) < 19 and element not in elements:
                elements[element] = _Element(element, int(count))
            case ["property", "list", count_type, item_type, prop] if {count_type, item_type} <= TYPES.keys():
                _last(elements, path, lineno).properties.append(_Property(prop, TYPES[item_type], TYPES[count_type]))
            case ["property", value_type, prop] if value_type in TYPES:
                _last(elements, path, lineno).properties.append(_Property(prop, TYPES[value_type]))
            case _:
                raise InvalidInput(f"{path.name}: PLY header line {lineno} is not understood: {shown(line.strip())}")
    if endian is None:
        raise InvalidInput(f"{path.name}: the PLY header has no 'format ascii|binary_little_endian|... 1.0' line")
    return _Header(endian, elements, len(lines) + 2)


def _last(elements: dict[str, _Element], path: Path, lineno: int) -> _Element:
    if not elements:
        raise InvalidInput(f"{path.name}: PLY header line {lineno} declares a property before any element")
    return next(reversed(elements.values()))


def _check_header(header: _Header, path: Path, size: int) -> None:
    vertex, face = header.elements.get("vertex"), header.elements.get("face")
    if vertex is None or not set(XYZ) <= {p.name for p in vertex.properties if p.count_code is None}:
        raise InvalidInput(f"{path.name}: the PLY header declares no 'vertex' element with x, y and z")
    if face is None or not any(p.name in FACE_LISTS and p.count_code for p in face.properties):
        raise InvalidInput(f"{path.name} has no faces (no 'face' element with a 'vertex_indices' list)")
    for element in header.elements.values():
        if not element.properties:
            raise InvalidInput(f"{path.name}: the PLY element '{element.name}' has no properties")
    need = sum(e.count * e.min_bytes(not header.endian) for e in header.elements.values())
    declared = ", ".join(f"{e.count} {e.name}" for e in header.elements.values())
    check_declared_size(path, declared, need, size)
    check_vertex_count(vertex.count, f"{path.name} declares")


# ----------------------------------------------------------------------------------------------------------
# ASCII body: one element per line


def _ascii_body(f: BinaryIO, path: Path, header: _Header) -> tuple[np.ndarray, Polygons]:
    lines = TextLines(f, path, "PLY", lineno=header.lines)
    found: dict[str, Any] = {}
    with line_errors(lines):
        for element in header.elements.values():
            found[element.name] = _collect(_ascii_rows(islice(lines, element.count), element), element)
    lines.reject_rest("the elements the header declares")
    return found["vertex"], found["face"]


def _ascii_rows(lines: Iterable[list[bytes]], element: _Element) -> Iterator[list[Any]]:
    """The wanted numbers of each line: x, y, z of a vertex, the ids of a face, nothing for other elements."""
    if element.name == "face" and len(element.properties) == 1:  # the usual face element: its list alone
        yield from (counted_ids(tokens) for tokens in lines)
        return
    if any(p.count_code for p in element.properties):
        yield from (_walk_line(tokens, element) for tokens in lines)
        return
    names = [p.name for p in element.properties]
    columns = [names.index(n) for n in element.wanted()]
    for tokens in lines:
        if len(tokens) < len(names):
            raise ValueError(f"a '{element.name}' line has fewer values than the header declares")
        yield numbers([tokens[i] for i in columns])


def _walk_line(tokens: list[bytes], element: _Element) -> list[Any]:
    """One line of an element with lists, walked property by property."""
    values, at = {}, 0
    for prop in element.properties:
        width = 1
        if prop.count_code:
            (width,) = numbers(tokens[at : at + 1], int) or [-1]
            if width < 0:
                raise ValueError(f"a list in a '{element.name}' line has no valid length")
            at += 1
        values[prop.name], at = tokens[at : at + width], at + width
    if at > len(tokens):
        raise ValueError(f"a '{element.name}' line has fewer values than the header declares")
    wanted = [t for n in element.wanted() if n in values for t in values[n]]
    return numbers(wanted, int if element.name == "face" else float)


def _collect(rows: Iterable[list[Any]], element: _Element) -> np.ndarray | Polygons:
    """Vertex coordinates as an (n, 3) array, faces as :class:`Polygons`; other elements only consumed."""
    if element.name == "vertex":
        return _complete(np.fromiter(rows, dtype=np.dtype((np.float64, 3))), element)
    corners, sizes = array("q"), array("q")
    for row in rows:
        corners.extend(row)
        sizes.append(len(row))
    return _complete(Polygons(np.frombuffer(corners, dtype=np.int64), np.frombuffer(sizes, dtype=np.int64)), element)


def _complete(values: np.ndarray | Polygons, element: _Element) -> np.ndarray | Polygons:
    n = len(values.sizes if isinstance(values, Polygons) else values)
    if element.wanted() and n < element.count:
        raise ValueError(f"the header promises {element.count} {element.name} lines, the file is shorter ({n})")
    return values


# ----------------------------------------------------------------------------------------------------------
# Binary body: fixed-size records read by numpy in one step, variable ones walked record by record


def _binary_body(data: bytes, path: Path, header: _Header) -> tuple[np.ndarray, Polygons]:
    found, at = {}, 0
    try:
        for element in header.elements.values():
            found[element.name], at = _fixed_records(data, at, element, header.endian) or _walk_records(
                data, at, element, header.endian
            )
    except (struct.error, ValueError):
        raise InvalidInput(
            f"{path.name} is not a valid PLY file: it ends inside element '{element.name}' "
            f"({element.count} declared); it is truncated or its header is wrong"
        ) from None
    if data[at:].strip():
        raise InvalidInput(
            f"{path.name} is not a valid PLY file: {len(data) - at} bytes follow the elements the header declares"
        )
    vertex = found["vertex"]
    faces = next(v for n, v in found["face"].items() if n in FACE_LISTS)
    with np.errstate(invalid="ignore"):  # a signalling NaN warns when widened; validation refuses it
        return np.column_stack([vertex[n] for n in XYZ]).astype(np.float64), faces


def _fixed_records(data: bytes, at: int, element: _Element, endian: str) -> tuple[dict[str, Any], int] | None:
    """All records at once when every list has the length it has in the first record (all triangles, say)."""
    lengths = _first_lengths(data, at, element, endian)
    if lengths is None:
        return None
    fields: list[tuple[Any, ...]] = []
    for i, prop in enumerate(element.properties):
        if prop.count_code:
            fields.append((f"n{i}", endian + prop.count_code))
        fields.append((f"v{i}", endian + prop.code, (lengths[i],) if prop.count_code else ()))
    dtype = np.dtype(fields)
    end = at + element.count * dtype.itemsize
    if end > len(data):
        return None
    records = np.frombuffer(data, dtype=dtype, count=element.count, offset=at)
    if any((records[f"n{i}"] != n).any() for i, n in lengths.items()):
        return None
    values: dict[str, Any] = {}
    for i, prop in enumerate(element.properties):
        if prop.name in element.wanted():
            v = records[f"v{i}"]
            values[prop.name] = Polygons(v.reshape(-1), np.full(len(v), lengths[i])) if prop.count_code else v
    return values, end


def _first_lengths(data: bytes, at: int, element: _Element, endian: str) -> dict[int, int] | None:
    """The length of each list property in the first record (index -> length); None if they do not fit."""
    lengths = {}
    for i, prop in enumerate(element.properties):
        if prop.count_code:
            if at + struct.calcsize(prop.count_code) > len(data):
                return None
            (lengths[i],) = struct.unpack_from(endian + prop.count_code, data, at) if element.count else (0,)
            at += struct.calcsize(prop.count_code) + max(lengths[i], 0) * struct.calcsize(prop.code)
        else:
            at += struct.calcsize(prop.code)
    return lengths if at <= len(data) and min(lengths.values(), default=0) >= 0 else None


def _walk_records(data: bytes, at: int, element: _Element, endian: str) -> tuple[dict[str, Any], int]:
    """Record by record (polygons of several sizes): slower, still linear in the file's size."""
    wanted = element.wanted()
    columns = {p.name: array("d") for p in element.properties if p.name in wanted and not p.count_code}
    lists = {p.name: (array("q"), array("q")) for p in element.properties if p.name in wanted and p.count_code}
    for _ in range(element.count):
        for prop in element.properties:
            if prop.count_code is None:
                if prop.name in columns:
                    columns[prop.name].append(struct.unpack_from(endian + prop.code, data, at)[0])
                at += struct.calcsize(prop.code)
                continue
            (count,) = struct.unpack_from(endian + prop.count_code, data, at)
            at += struct.calcsize(prop.count_code)
            if count < 0 or at + count * struct.calcsize(prop.code) > len(data):
                raise ValueError("list longer than the file")
            if prop.name in lists:
                lists[prop.name][0].extend(struct.unpack_from(f"{endian}{count}{prop.code}", data, at))
                lists[prop.name][1].append(count)
            at += count * struct.calcsize(prop.code)
    values: dict[str, np.ndarray | Polygons] = {n: np.frombuffer(c, dtype=np.float64) for n, c in columns.items()}
    for n, (corners, sizes) in lists.items():
        values[n] = Polygons(np.frombuffer(corners, dtype=np.int64), np.frombuffer(sizes, dtype=np.int64))
    return values, at
