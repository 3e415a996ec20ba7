"""Peak memory and time of ``load_mesh`` against file size, for every format we read.

Meshes are subdivided icospheres (10k, 40k and 160k vertices by default), written as OFF, OBJ, PLY (ASCII
and binary), STL (binary and ASCII) and GLB. Each file is loaded in a fresh Python process that has already
imported what loading might need (numpy, open3d, trimesh); ``peak_bytes`` is the growth of that process's
resident memory from just before the load to its peak during the load (``VmHWM`` after resetting it through
``/proc/self/clear_refs``: Linux only; ``ru_maxrss`` cannot be reset and still holds the imports' peak), so it
counts every allocation (numpy, Python, C++), and ``peak_per_file_byte`` divides it by the file's size.
``--code DIR`` loads with the ``curvefm`` package found in DIR/src or DIR instead (another checkout), to compare.

Usage: ``python -m benchmarks.bench_mesh_parse [--subdivisions 5 6 7] [--code DIR]``; prints JSON.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
from datetime import date
from pathlib import Path

import open3d as o3d
import trimesh

from curvefm.geometry import build_mesh, save_mesh

FORMATS = ["off", "obj", "ply_ascii", "ply_binary", "stl_binary", "stl_ascii", "glb"]

CHILD = """
import json, sys, time
sys.path[:0] = [{code!r} + '/src', {code!r}]  # a src/ layout checkout, or an older flat one
import numpy, open3d, trimesh, curvefm
from curvefm.geometry import load_mesh

def status(key):  # kB in /proc/self/status
    return next(int(line.split()[1]) for line in open("/proc/self/status") if line.startswith(key + ":"))

before = status("VmRSS")
open("/proc/self/clear_refs", "w").write("5")  # peak resident memory := current, so VmHWM is this load's peak
start = time.perf_counter()
mesh = load_mesh({path!r})
seconds = time.perf_counter() - start
print(json.dumps({{"seconds": seconds, "peak_bytes": 1024 * (status("VmHWM") - before), "vertices": mesh.n_vertices,
                  "faces": len(mesh.faces), "curvefm": curvefm.__file__}}))
"""


def write(mesh, folder: Path, fmt: str) -> Path:
    """The mesh in one format: ``save_mesh`` where it writes it, open3d for ASCII PLY, trimesh for the rest."""
    suffix = fmt.split("_")[0]
    path = folder / f"{fmt}.{suffix}"
    if fmt in ("off", "obj", "ply_binary", "stl_binary"):
        save_mesh(mesh, path)
    elif fmt == "ply_ascii":
        m = o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(mesh.vertices), o3d.utility.Vector3iVector(mesh.faces))
        o3d.io.write_triangle_mesh(str(path), m, write_ascii=True)
    else:
        file_type = {"stl_ascii": "stl_ascii", "glb": "glb"}[fmt]
        trimesh.Trimesh(mesh.vertices, mesh.faces, process=False).export(path, file_type=file_type)
    return path


def measure(path: Path, code: Path) -> dict:
    script = CHILD.format(code=str(code), path=str(path))
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True)
    if out.returncode:
        return {"error": out.stderr.strip().splitlines()[-1]}
    result = json.loads(out.stdout)
    assert Path(result["curvefm"]).is_relative_to(code), f"loaded {result['curvefm']}, not the code in {code}"
    size = path.stat().st_size
    return {
        "file_bytes": size,
        "seconds": round(result["seconds"], 3),
        "peak_bytes": result["peak_bytes"],
        "peak_per_file_byte": round(result["peak_bytes"] / size, 2),
        "vertices": result["vertices"],
        "faces": result["faces"],
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--subdivisions", type=int, nargs="+", default=[5, 6, 7])
    parser.add_argument("--code", type=Path, default=Path(__file__).resolve().parents[1])
    args = parser.parse_args()
    results = []
    with tempfile.TemporaryDirectory(prefix="curvefm-bench-parse-") as folder:
        for level in args.subdivisions:
            sphere = trimesh.creation.icosphere(subdivisions=level)
            mesh = build_mesh(sphere.vertices, sphere.faces)
            for fmt in FORMATS:
                path = write(mesh, Path(folder), fmt)
                results.append({"format": fmt, "mesh_vertices": mesh.n_vertices, **measure(path, args.code)})
                path.unlink()
    machine = {"date": date.today().isoformat(), "cpus": os.cpu_count(), "python": platform.python_version()}
    print(json.dumps({"machine": machine, "code": str(args.code), "results": results}, indent=1))


if __name__ == "__main__":
    main()
