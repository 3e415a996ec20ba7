"""The whole pipeline for two meshes and a list of corresponding curves, as the CLI and scripts use it.

:func:`match` is ``curvefm match``. A refinement job (``curvefm.workers.jobs.refine``) solves a session's maps
its own way and shares the rest: :func:`pair_with_basis_size`, :func:`convert` and :func:`write_outputs`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from pydantic import BaseModel

from curvefm import registry
from curvefm.errors import InvalidInput
from curvefm.fmap import DEFAULT_K, FunctionalMaps, Hints, transfer
from curvefm.geometry import Mesh, save_mesh, texture_coordinates
from curvefm.pointwise import PointwiseMaps
from curvefm.progress import Progress, no_progress, scaled
from curvefm.registry import ConverterPlugin
from curvefm.session import CurveSpec, trace_pair
from curvefm.spectral import ShapePair
from curvefm.store import Store


@dataclass(frozen=True)
class MatchResult:
    """Functional maps both ways on ``pair`` and the pointwise maps converted from them.

    ``pair`` holds the full bases, which may have more functions than the maps' k (a converter such as ZoomOut
    works in larger ones); ``paths`` are the corresponding curves ``(path_M, path_N)`` (internal ids).
    """

    pair: ShapePair
    fmaps: FunctionalMaps
    maps: PointwiseMaps
    method: str = "curves"
    paths: tuple[tuple[np.ndarray, np.ndarray], ...] = ()


def pair_with_basis_size(
    store: Store,
    meshes: tuple[Mesh, Mesh],
    k: int,
    plugin: str = "laplace-beltrami",
    params: dict | None = None,
    progress: Progress = no_progress,
) -> ShapePair:
    """Both meshes with their stored bases of ``k`` functions, computed and stored where missing."""
    mesh_M, mesh_N = meshes
    basis_M = store.ensure_basis(mesh_M, k, plugin, params, scaled(progress, 0.0, 0.5))
    basis_N = store.ensure_basis(mesh_N, k, plugin, params, scaled(progress, 0.5, 1.0))
    return ShapePair(mesh_M, mesh_N, basis_M, basis_N)


def convert(
    pair: ShapePair,
    fmaps: FunctionalMaps,
    converter: ConverterPlugin,
    params: BaseModel,
    progress: Progress = no_progress,
    method: str = "curves",
    paths: Sequence[tuple[np.ndarray, np.ndarray]] = (),
) -> MatchResult:
    """Pointwise maps from ``fmaps`` by a converter with its parsed ``params``. Give ``pair`` bases of
    ``converter.basis_size(params)`` functions where the store has them; else the converter computes them."""
    return MatchResult(pair, fmaps, converter.run(pair, fmaps, params, progress), method, tuple(paths))


def match(
    mesh_M: Mesh,
    mesh_N: Mesh,
    curves: list[CurveSpec] | list[tuple[np.ndarray, np.ndarray]],
    k: int = DEFAULT_K,
    alpha: float | None = None,
    tracer: str = "geodesic",
    converter: str = "nearest-neighbor",
    converter_params: dict | None = None,
    store: Store | None = None,
    samples: int | None = None,
    progress: Progress = no_progress,
    method: str = "combined",
    method_params: dict | None = None,
) -> MatchResult:
    """Bases (from the store or computed), curves traced, both functional maps, pointwise maps.

    ``curves`` are :class:`CurveSpec` (file ids, traced here) or ready ``(path_M, path_N)`` internal paths.
    ``method`` is a map-method plugin (``combined``, the default, and ``curves`` are ours; ``obcs12`` and ``no17``
    use the curves' endpoints as landmarks); ``alpha`` and ``samples``, where given, go to the methods that take
    them (else each method's own default).
    """
    store = store or Store()
    method_plugin = registry.get("method", method)
    shared = {name: value for name, value in {"alpha": alpha, "samples": samples}.items()
              if value is not None and name in method_plugin.Params.model_fields}  # fmt: skip
    method_parsed = method_plugin.parse_params(shared | (method_params or {}))
    converter_plugin, converter_parsed = registry.load("converter", converter, converter_params)
    basis_k = max(k, converter_plugin.basis_size(converter_parsed))  # refiners such as ZoomOut use larger bases
    pair = pair_with_basis_size(store, (mesh_M, mesh_N), basis_k, progress=scaled(progress, 0.0, 0.8))
    paths = [trace_pair(mesh_M, mesh_N, c, tracer) if isinstance(c, CurveSpec) else c for c in curves]
    if not paths:
        raise InvalidInput("at least one pair of curves is needed to compute a map")
    weights = [c.weight if isinstance(c, CurveSpec) else 1.0 for c in curves]
    fmaps = method_plugin.run(pair.truncated(k), Hints.from_curves(paths, weights), method_parsed, no_progress)
    return convert(pair, fmaps, converter_plugin, converter_parsed, scaled(progress, 0.8, 1.0), method, paths)


def write_outputs(result: MatchResult, out_dir: str | Path) -> list[Path]:
    """The files of ``curvefm match``; maps are written per **file** vertex in file ids (-1 for a dropped
    vertex), one integer per line: ``map_target_to_source.txt`` line j = source vertex for target vertex j."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    mesh_M, mesh_N, maps = result.pair.mesh_M, result.pair.mesh_N, result.maps
    np.save(out / "C_source_to_target.npy", result.fmaps.C_MN)
    np.save(out / "C_target_to_source.npy", result.fmaps.C_NM)
    files = [out / "C_source_to_target.npy", out / "C_target_to_source.npy"]
    for name, p2p, image, domain in (
        ("map_target_to_source.txt", maps.p2p_NM, mesh_M, mesh_N),
        ("map_source_to_target.txt", maps.p2p_MN, mesh_N, mesh_M),
    ):
        np.savetxt(out / name, domain.per_file_vertex(image.file_ids[p2p], -1), fmt="%d")
        files.append(out / name)
    uv_N = transfer(result.fmaps.C_MN, result.pair.basis_M, result.pair.basis_N, texture_coordinates(mesh_M))
    save_mesh(mesh_N, out / "target_textured.obj", uv=uv_N)
    files.append(out / "target_textured.obj")
    return files
