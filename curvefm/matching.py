"""The whole pipeline for two meshes and a list of corresponding curves, as the CLI and scripts use it."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from pydantic import BaseModel

from curvefm import registry
from curvefm.errors import CurvefmError
from curvefm.fmap import DEFAULT_ALPHA, DEFAULT_K, DEFAULT_SAMPLES, MapInputs, transfer
from curvefm.geometry import Mesh, save_mesh, texture_coordinates
from curvefm.pointwise import MapProblem, PointwiseMaps
from curvefm.progress import Progress, no_progress, scaled
from curvefm.session import CurveSpec, trace_pair
from curvefm.spectral import Basis
from curvefm.store import Store


def converter_basis_size(params: BaseModel) -> int:
    """Basis functions per shape a converter works with (its params' ``basis_size()``, 0 if it has none)."""
    return params.basis_size() if hasattr(params, "basis_size") else 0


@dataclass
class MatchResult:
    mesh_M: Mesh
    mesh_N: Mesh
    basis_M: Basis
    basis_N: Basis
    C_MN: np.ndarray
    C_NM: np.ndarray
    method: str = "curves"
    maps: PointwiseMaps | None = None
    paths: list[tuple[np.ndarray, np.ndarray]] = field(default_factory=list)

    def problem(self) -> MapProblem:
        """The converter's input: the full bases (they may hold more functions than the maps' k)."""
        return MapProblem(
            self.mesh_M.vertices, self.mesh_M.faces, self.basis_M,
            self.mesh_N.vertices, self.mesh_N.faces, self.basis_N,
            self.C_MN, self.C_NM,
        )  # fmt: skip


def match(
    mesh_M: Mesh,
    mesh_N: Mesh,
    curves: list[CurveSpec] | list[tuple[np.ndarray, np.ndarray]],
    k: int = DEFAULT_K,
    alpha: float = DEFAULT_ALPHA,
    tracer: str = "geodesic",
    converter: str = "nearest-neighbor",
    converter_params: dict | None = None,
    store: Store | None = None,
    samples: int = DEFAULT_SAMPLES,
    progress: Progress = no_progress,
    method: str = "curves",
    method_params: dict | None = None,
) -> MatchResult:
    """Bases (from the store or computed), curves traced, both functional maps, pointwise maps.

    ``curves`` are :class:`CurveSpec` (file ids, traced here) or ready ``(path_M, path_N)`` internal paths.
    ``method`` is a map-method plugin (``curves``, ours, by default; ``obcs12`` and ``no17`` use the curves'
    endpoints as landmarks); ``alpha`` and ``samples`` are defaults for the methods that take them.
    """
    store = store or Store()
    compute = registry.get("method", method)
    shared = {"alpha": alpha, "samples": samples}
    compute_params = compute.parse_params(
        {name: value for name, value in shared.items() if name in compute.Params.model_fields} | (method_params or {})
    )
    convert = registry.get("converter", converter)
    parsed = convert.parse_params(converter_params)
    basis_k = max(k, converter_basis_size(parsed))  # refiners such as ZoomOut work in larger bases
    basis_M = store.ensure_basis(mesh_M, basis_k, progress=scaled(progress, 0.0, 0.4))
    basis_N = store.ensure_basis(mesh_N, basis_k, progress=scaled(progress, 0.4, 0.8))
    paths = [trace_pair(mesh_M, mesh_N, c, tracer) if isinstance(c, CurveSpec) else c for c in curves]
    if not paths:
        raise CurvefmError("at least one pair of curves is needed to compute a map")
    weights = [c.weight if isinstance(c, CurveSpec) else 1.0 for c in curves]
    inputs = MapInputs.from_curves(mesh_M, mesh_N, basis_M.truncated(k), basis_N.truncated(k), paths, weights)
    fmaps = compute.run(inputs, compute_params)
    result = MatchResult(mesh_M, mesh_N, basis_M, basis_N, fmaps.C_MN, fmaps.C_NM, method, paths=paths)
    result.maps = convert.run(result.problem(), parsed, scaled(progress, 0.8, 1.0))
    return result


def write_outputs(result: MatchResult, out_dir: str | Path) -> list[Path]:
    """The files of ``curvefm match``; maps are written per **file** vertex in file ids (-1 for a dropped
    vertex), one integer per line: ``map_target_to_source.txt`` line j = source vertex for target vertex j."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    mesh_M, mesh_N, maps = result.mesh_M, result.mesh_N, result.maps
    np.save(out / "C_source_to_target.npy", result.C_MN)
    np.save(out / "C_target_to_source.npy", result.C_NM)
    files = [out / "C_source_to_target.npy", out / "C_target_to_source.npy"]
    for name, p2p, image, domain in (
        ("map_target_to_source.txt", maps.p2p_NM, mesh_M, mesh_N),
        ("map_source_to_target.txt", maps.p2p_MN, mesh_N, mesh_M),
    ):
        np.savetxt(out / name, domain.per_file_vertex(image.file_ids[p2p], -1), fmt="%d")
        files.append(out / name)
    uv_N = transfer(result.C_MN, result.basis_M, result.basis_N, texture_coordinates(mesh_M))
    save_mesh(mesh_N, out / "target_textured.obj", uv=uv_N)
    files.append(out / "target_textured.obj")
    return files
