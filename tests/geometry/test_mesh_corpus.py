"""The malformed-mesh corpus (tests/support/mesh_corpus.py, written when the tests run): every file gives the
documented outcome through ``load_mesh``, opens nothing outside its folder, and headers declaring far more
than the file holds cost memory in proportion to the file, not to the header."""

import json
import subprocess
import sys
import textwrap
import tracemalloc
from pathlib import Path

import pytest
import trimesh  # noqa: F401  (its first import reads package metadata: not a file the reader opens)
from support.mesh_corpus import MANIFEST, corpus_dir, files

from curvefm.errors import CurvefmError
from curvefm.geometry import load_mesh

CORPUS = corpus_dir()
MESHES = CORPUS / "meshes"
HUGE = sorted(name for name, expected in MANIFEST.items() if expected.get("huge"))
FIXED_BYTES, BYTES_PER_FILE_BYTE = 256 * 1024, 16  # the memory a huge-header file may cost to refuse

OPENED: list[str] | None = None  # paths opened while a load is watched
PYTHON = {Path(p).resolve() for p in (sys.prefix, sys.base_prefix)}  # modules and their resources


def _record_open(event: str, args: tuple) -> None:
    if OPENED is not None and event == "open" and isinstance(args[0], str | bytes | Path):
        OPENED.append(str(Path(args[0] if not isinstance(args[0], bytes) else args[0].decode()).resolve()))


sys.addaudithook(_record_open)


def watched_load(path: Path):
    """``load_mesh(path)`` with the peak of Python (and numpy) allocations and the files it opened."""
    global OPENED
    OPENED = []
    tracemalloc.start()
    try:
        return load_mesh(path), tracemalloc.get_traced_memory()[1], OPENED
    except CurvefmError as exc:
        return exc, tracemalloc.get_traced_memory()[1], OPENED
    finally:
        tracemalloc.stop()
        OPENED = None


def test_the_corpus_holds_a_file_for_every_case():
    assert sorted(p.name for p in MESHES.iterdir()) == sorted(Path(n).name for n in files() if n.startswith("meshes/"))
    assert set(MANIFEST) <= {p.name for p in MESHES.iterdir()}
    assert len(MANIFEST) >= 40


@pytest.mark.parametrize("name", sorted(MANIFEST))
def test_each_file_gives_its_documented_outcome(name):
    expected = MANIFEST[name]
    result, peak, opened = watched_load(MESHES / name)
    outside = [p for p in opened if not any(Path(p).is_relative_to(r) for r in {MESHES.resolve(), *PYTHON})]
    assert not outside, f"{name} opened {outside}"
    if expected["expect"] == "reject":
        assert isinstance(result, CurvefmError), f"{name} was accepted"
        assert expected["message"] in result.message and result.code == expected["kind"], result.message
    else:
        assert not isinstance(result, CurvefmError), result.message
        assert (result.n_vertices, len(result.faces)) == (expected["vertices"], expected["faces"])
        assert (result.uv is not None) == expected["uv"]
        assert (result.texture_path and Path(result.texture_path).name) == expected["texture"]
    if expected.get("huge"):
        assert peak < FIXED_BYTES + BYTES_PER_FILE_BYTE * (MESHES / name).stat().st_size, f"peak {peak} bytes"


def test_polygon_soup_is_accepted_and_its_components_reported():
    for name in ("soup.off", "soup.obj", "soup.stl"):
        assert load_mesh(MESHES / name).report.components == 2


def test_u_only_texture_coordinates_mean_v_zero():
    mesh = load_mesh(MESHES / "vt_mixed.obj")
    assert mesh.uv.tolist() == [[0.1, 0.0], [0.2, 0.5], [0.3, 0.7]]


def test_huge_headers_cost_little_resident_memory():
    """The same files in a fresh process, measured by the kernel (any allocation, not only Python's)."""
    script = textwrap.dedent(
        f"""
        import json, resource, sys
        from curvefm.errors import CurvefmError
        from curvefm.geometry import load_mesh
        growth = {{}}
        for name in {HUGE!r}:
            before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
            try:
                load_mesh({str(MESHES)!r} + "/" + name)
            except CurvefmError:
                pass
            growth[name] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before
        print(json.dumps(growth))
        """
    )
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, check=True).stdout
    growth_kib = json.loads(out)
    assert set(growth_kib) == set(HUGE)
    assert max(growth_kib.values()) < 16 * 1024, growth_kib


@pytest.mark.parametrize("name", ["ok.off", "ok_ascii.ply", "ok_binary.ply", "ok.gltf"])
def test_declared_vertex_counts_above_the_limit_are_refused_before_reading(monkeypatch, name):
    monkeypatch.setenv("CURVEFM_MAX_VERTICES", "2")
    result, peak, _ = watched_load(MESHES / name)
    assert isinstance(result, CurvefmError) and result.code == "too_large", result
    assert "declares 3 vertices, more than the limit of 2" in result.message


def test_obj_vertices_beyond_the_limit_stop_the_reader(monkeypatch, tmp_path):
    monkeypatch.setenv("CURVEFM_MAX_VERTICES", "2")
    (tmp_path / "m.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    with pytest.raises(CurvefmError, match="more than the limit of 2") as info:
        load_mesh(tmp_path / "m.obj")
    assert info.value.code == "too_large"


@pytest.mark.parametrize("suffix", [".off", ".obj", ".ply", ".stl"])
def test_a_line_too_long_for_a_text_mesh_is_refused_before_it_is_split(tmp_path, suffix):
    heads = {".off": b"OFF\n", ".obj": b"", ".ply": b"ply\nformat ascii 1.0\n", ".stl": b"solid x\n"}
    path = tmp_path / f"long{suffix}"
    path.write_bytes(heads[suffix] + b"0 " * 40_000 + b"\n")
    with pytest.raises(CurvefmError, match="longer than 65536 bytes|no 'end_header'"):
        load_mesh(path)
