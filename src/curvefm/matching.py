"""The whole pipeline for two meshes and a list of corresponding curves, as the CLI and scripts use it.

:func:`match` is ``curvefm match``. A refinement job (``curvefm.workers.jobs.refine``) solves a session's maps
its own way and shares the rest: :func:`pair_with_basis_size`, :func:`convert` and :func:`write_outputs`.
"""

from __future__ import annotations

from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, BinaryIO

import numpy as np
import scipy.io
from pydantic import BaseModel

from curvefm import registry
from curvefm.errors import InvalidInput
from curvefm.fmap import DEFAULT_K, FunctionalMaps, Hints, transfer
from curvefm.geometry import Mesh, save_textured, texture_coordinates, zip_files
from curvefm.pointwise import PointwiseMaps, compare, fmap_from_pointwise, measure
from curvefm.progress import Progress, no_progress, scaled, shared
from curvefm.registry import ConverterPlugin
from curvefm.session import CurveSpec, pinned_pieces, trace_pair
from curvefm.spectral import ShapePair
from curvefm.store import Store

DEFAULT_CONVERTER = "nearest-neighbor"
"""The converter of ``curvefm match`` and of the service: the pointwise maps a person gets (with its defaults,
:func:`handed_out`)."""
BASES_AT_ONCE_MAX_VERTICES = 1_000_000
"""The pair of 440,834-vertex meshes still computes its bases at once (6.4 GB for the whole match)."""


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
    quality: dict[str, Any] = field(default_factory=dict)
    """Intrinsic figures (:mod:`curvefm.pointwise.quality`): ``{"converted": ...}``, and for a refining
    converter also ``"initial"`` (the nearest-neighbour maps it started from) and ``"refined"``."""
    kept: str = "converted"
    """For a refining converter which maps ``maps`` are: ``"refined"``, ``"stopped"`` (the refinement stopped at
    an earlier stage) or ``"initial"``; else ``"converted"``."""
    reason: str = ""
    refined_fmaps: FunctionalMaps | None = None
    """Where refined (or stopped) pointwise maps are kept: the functional maps they induce at the converter's basis
    size (ZoomOut's k_final), which :attr:`exported_fmaps` hands out instead of ``fmaps``."""

    @property
    def exported_fmaps(self) -> FunctionalMaps:
        """The functional maps written out with the pointwise maps: the refined ones where there are, else ``fmaps``."""
        return self.refined_fmaps or self.fmaps

    def describe_fmaps(self) -> str:
        """What the written functional maps are, in a sentence."""
        rows, columns = self.exported_fmaps.C_MN.shape
        if self.refined_fmaps is None:
            return f"the functional maps as solved, {rows} x {columns}"
        return f"the functional maps the {self.kept} pointwise maps induce at the converter's size, {rows} x {columns}"

    def summary(self) -> dict[str, Any]:
        """What a job result and ``curvefm match`` report about the maps: figures, which were kept and why, and
        the size and origin of the functional maps written with them."""
        C_MN = self.exported_fmaps.C_MN
        fmaps = {"size": list(C_MN.shape), "what": self.describe_fmaps()}
        return {"kept": self.kept, "reason": self.reason, "quality": self.quality, "functional_maps": fmaps}


def pair_with_basis_size(
    store: Store,
    meshes: tuple[Mesh, Mesh],
    k: int,
    plugin: str = "laplace-beltrami",
    params: dict[str, Any] | None = None,
    progress: Progress = no_progress,
) -> ShapePair:
    """Both meshes with their stored bases of ``k`` functions, computed and stored where missing.

    Two different meshes' bases are computed at once, in two threads: the eigensolvers' factorisations and
    products release the GIL for part of their time (440k vertices a mesh: 63 s one after the other, 52 s at
    once, 2026-11-23 beside other work). Above :data:`BASES_AT_ONCE_MAX_VERTICES` vertices in all they are computed
    one after the other: two at once need both solvers' memory (docs/performance.md, "Scans of millions")."""
    mesh_M, mesh_N = meshes
    if mesh_M.content_hash == mesh_N.content_hash:
        basis = store.ensure_basis(mesh_M, k, plugin, params, progress)
        return ShapePair(mesh_M, mesh_N, basis, basis)
    if mesh_M.n_vertices + mesh_N.n_vertices > BASES_AT_ONCE_MAX_VERTICES:
        parts = shared(progress, 2)
        basis_M = store.ensure_basis(mesh_M, k, plugin, params, parts[0])
        return ShapePair(mesh_M, mesh_N, basis_M, store.ensure_basis(mesh_N, k, plugin, params, parts[1]))
    with ThreadPoolExecutor(2, thread_name_prefix="curvefm-basis") as pool:
        futures = [
            pool.submit(store.ensure_basis, mesh, k, plugin, params, part)
            for mesh, part in zip(meshes, shared(progress, 2), strict=True)
        ]
        basis_M, basis_N = (future.result() for future in futures)
    return ShapePair(mesh_M, mesh_N, basis_M, basis_N)


def convert(
    pair: ShapePair,
    fmaps: FunctionalMaps,
    converter: ConverterPlugin[Any],
    params: BaseModel,
    progress: Progress = no_progress,
    method: str = "curves",
    paths: Sequence[tuple[np.ndarray, np.ndarray]] = (),
) -> MatchResult:
    """Pointwise maps from ``fmaps`` by a converter with its parsed ``params``, given the user's curves
    ``paths`` (refiners keep them). Give ``pair`` bases of ``converter.basis_size(params)`` functions where the
    store has them; else the converter computes them.

    A refining converter's maps are returned only if no intrinsic figure got worse than the maps the user gets
    without refinement, the ``nearest-neighbor`` converter's with its defaults (:func:`curvefm.pointwise.compare`).
    Otherwise the first of the converter's earlier stages (``ConverterPlugin.stages``: ZoomOut stopped at a smaller
    size) that made none worse is, or, failing that, the initial maps; ``reason`` names the figures that got
    worse and ``quality["refined"]`` holds the figures of the whole refinement. Refined or stopped maps come with
    the functional maps they induce at the converter's basis size (``refined_fmaps``, :func:`induced_fmaps`)."""
    paths = tuple(paths)
    stages = converter.convert_in_stages(pair, fmaps, params, progress, paths)
    _, maps = next(stages)
    quality = measure(pair, maps, paths)
    if not converter.refines:
        return MatchResult(pair, fmaps, maps, method, paths, {"converted": quality.as_dict()})
    start = handed_out(pair, fmaps)
    start_quality = measure(pair, start, paths)
    worse = compare(quality, start_quality)
    figures = {"initial": start_quality.as_dict(), "refined": quality.as_dict()}
    size = converter.basis_size(params) or len(fmaps.C_MN)
    if not worse:
        reason = f"'{converter.name}' made no intrinsic figure worse than the initial maps"
        refined = induced_fmaps(pair, maps, size)
        return MatchResult(pair, fmaps, maps, method, paths, figures, "refined", reason, refined)
    worse_text = f"'{converter.name}' made the map worse ({'; '.join(worse)})"
    for label, earlier in stages:
        progress(1.0, f"{worse_text}; checking it stopped at {label}")  # also where a cancelled job stops
        earlier_quality = measure(pair, earlier, paths)
        if not compare(earlier_quality, start_quality):
            figures["stopped"] = {"at": label} | earlier_quality.as_dict()
            reason = f"{worse_text}; stopped at {label} it made no figure worse: those maps are returned"
            refined = induced_fmaps(pair, earlier, size)
            return MatchResult(pair, fmaps, earlier, method, paths, figures, "stopped", reason, refined)
    reason = f"{worse_text}: the initial maps are returned"
    return MatchResult(pair, fmaps, start, method, paths, figures, "initial", reason)


def induced_fmaps(pair: ShapePair, maps: PointwiseMaps, size: int) -> FunctionalMaps:
    """Both functional maps (size x size, at most the bases' size) that pointwise maps induce, ``Psi^+ Pi Phi``:
    what ZoomOut fits at its last size, and for any refiner the functional maps of its pointwise maps."""
    k = min(size, pair.basis_M.k, pair.basis_N.k)
    return FunctionalMaps(
        fmap_from_pointwise(maps.p2p_NM, pair.basis_M, pair.basis_N, k, k),
        fmap_from_pointwise(maps.p2p_MN, pair.basis_N, pair.basis_M, k, k),
    )


def handed_out(pair: ShapePair, fmaps: FunctionalMaps) -> PointwiseMaps:
    """The pointwise maps ``curvefm match`` hands out for ``fmaps`` unrefined: the :data:`DEFAULT_CONVERTER`'s with
    its defaults (nearest neighbours, then its orthogonal steps)."""
    converter, defaults = registry.load("converter", DEFAULT_CONVERTER, None)
    return converter.run(pair, fmaps, defaults)


def match(
    mesh_M: Mesh,
    mesh_N: Mesh,
    curves: list[CurveSpec] | list[tuple[np.ndarray, np.ndarray]],
    k: int = DEFAULT_K,
    alpha: float | None = None,
    tracer: str = "geodesic",
    converter: str = DEFAULT_CONVERTER,
    converter_params: dict[str, Any] | None = None,
    store: Store | None = None,
    samples: int | None = None,
    progress: Progress = no_progress,
    method: str = "combined",
    method_params: dict[str, Any] | None = None,
) -> MatchResult:
    """Bases (from the store or computed), curves traced, both functional maps, pointwise maps.

    ``curves`` are :class:`CurveSpec` (file ids, traced here) or ready ``(path_M, path_N)`` internal paths.
    ``method`` is a map-method plugin (``combined``, the default, and ``curves`` are ours; ``obcs12`` and ``no17``
    use the curves' endpoints as landmarks); ``alpha`` and ``samples``, where given, go to the methods that take
    them (else each method's own default).
    """
    store = store or Store()
    method_plugin = registry.get("method", method)
    shared = {
        name: value
        for name, value in {"alpha": alpha, "samples": samples}.items()
        if value is not None and name in method_plugin.Params.model_fields
    }
    method_parsed = method_plugin.parse_params(shared | (method_params or {}))
    converter_plugin, converter_parsed = registry.load("converter", converter, converter_params)
    basis_k = max(k, converter_plugin.basis_size(converter_parsed))  # refiners such as ZoomOut use larger bases
    pair = pair_with_basis_size(store, (mesh_M, mesh_N), basis_k, progress=scaled(progress, 0.0, 0.8))
    paths = [trace_pair(mesh_M, mesh_N, c, tracer) if isinstance(c, CurveSpec) else c for c in curves]
    if not paths:
        raise InvalidInput("at least one pair of curves is needed to compute a map")
    weights = [c.weight if isinstance(c, CurveSpec) else 1.0 for c in curves]
    fmaps = method_plugin.run(pair.truncated(k), Hints.from_curves(paths, weights), method_parsed, no_progress)
    pieces = [
        piece
        for c, (path_M, path_N) in zip(curves, paths, strict=True)
        for piece in (
            pinned_pieces(mesh_M, mesh_N, c, path_M, path_N) if isinstance(c, CurveSpec) else [(path_M, path_N)]
        )
    ]
    return convert(pair, fmaps, converter_plugin, converter_parsed, scaled(progress, 0.8, 1.0), method, pieces)


def mat_note(arrays: dict[str, np.ndarray], about: str = "") -> str:
    """What a maps ``.mat`` holds, array by array, after ``about`` (where its maps come from)."""
    rows, columns = arrays["C_source_to_target"].shape
    back_rows, back_columns = arrays["C_target_to_source"].shape
    parts = [about] if about else []
    parts.append(
        f"C_source_to_target ({rows} x {columns}) takes the coefficients of a function on the source (its basis's "
        f"first {columns} functions, shape scaled to unit area) to coefficients on the target (its first {rows}); "
        f"C_target_to_source ({back_rows} x {back_columns}) the other way."
    )
    if "map_target_to_source" in arrays:
        parts.append(
            "map_target_to_source(j + 1) is the source vertex of target vertex j, map_source_to_target(i + 1) the "
            "target vertex of source vertex i: 0-based file vertex ids (add 1 to index MATLAB arrays), -1 for a "
            "vertex of no face."
        )
    else:
        parts.append("No pointwise maps: a refinement's maps.mat holds them.")
    return " ".join(parts)


def save_maps_mat(
    out: str | Path | BinaryIO, C_MN: np.ndarray, C_NM: np.ndarray, about: str = "", **maps: np.ndarray
) -> None:
    """Both functional maps (and pointwise ``maps`` by name, e.g. ``map_target_to_source``) as a MATLAB
    ``.mat`` file (version 5, what ``load`` reads), with a ``note`` saying what it holds (:func:`mat_note`) after
    ``about``."""
    arrays = {"C_source_to_target": C_MN, "C_target_to_source": C_NM, **maps}
    note = mat_note(arrays, about)
    # scipy-stubs type file_name as a path; scipy also writes to a file object (the service's downloads)
    scipy.io.savemat(out, {**arrays, "note": note}, do_compression=True, oned_as="column")  # type: ignore[arg-type]


def write_outputs(result: MatchResult, out_dir: str | Path, about: str = "") -> list[Path]:
    """The files of ``curvefm match``; maps are written per **file** vertex in file ids (-1 for a dropped
    vertex), one integer per line: ``map_target_to_source.txt`` line j = source vertex for target vertex j.
    The functional maps are :attr:`MatchResult.exported_fmaps` (a refinement's at its final size).
    ``maps.mat`` holds both functional and pointwise maps for MATLAB, its note saying what they are after
    ``about``; the textured target as ``target_textured.obj`` with its material ``.mtl`` and texture ``.png``
    beside it, and the three in ``target_textured.zip``."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    mesh_M, mesh_N, maps, fmaps = result.pair.mesh_M, result.pair.mesh_N, result.maps, result.exported_fmaps
    np.save(out / "C_source_to_target.npy", fmaps.C_MN)
    np.save(out / "C_target_to_source.npy", fmaps.C_NM)
    files = [out / "C_source_to_target.npy", out / "C_target_to_source.npy"]
    pointwise = {}
    for name, p2p, image, domain in (
        ("map_target_to_source", maps.p2p_NM, mesh_M, mesh_N),
        ("map_source_to_target", maps.p2p_MN, mesh_N, mesh_M),
    ):
        pointwise[name] = domain.per_file_vertex(image.file_ids[p2p], -1)
        np.savetxt(out / f"{name}.txt", pointwise[name], fmt="%d")
        files.append(out / f"{name}.txt")
    about = f"{about} " if about else ""
    about += f"Functional maps: {result.describe_fmaps()}; pointwise maps: {result.kept}."
    save_maps_mat(out / "maps.mat", fmaps.C_MN, fmaps.C_NM, about, **pointwise)
    uv_N = transfer(fmaps.C_MN, result.pair.basis_M, result.pair.basis_N, texture_coordinates(mesh_M))
    textured = save_textured(mesh_N, uv_N, out, "target_textured")  # written once, then zipped (scans: ~16 s each)
    zip_files(textured, out / "target_textured.zip")
    return files + [out / "maps.mat", *textured, out / "target_textured.zip"]
