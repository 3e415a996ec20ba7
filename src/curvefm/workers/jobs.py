"""Job functions: plain importable functions with plain arguments, run by RQ workers or the embedded executor.

Each returns a small JSON-able dict. Files go under the data directory: bases into the content-addressed
store, refinement results into ``<data>/results/<job id>/`` (published all at once by a directory rename).
"""

from __future__ import annotations

import dataclasses
import shutil
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from curvefm import registry
from curvefm.errors import InvalidInput
from curvefm.fmap import FunctionalMaps
from curvefm.matching import MatchResult, convert, pair_with_basis_size, write_outputs
from curvefm.progress import scaled
from curvefm.session import SessionRecord, build_solver, internal_paths, load_pair, pinned_pieces, stated_solve
from curvefm.store import Store, params_key
from curvefm.workers.context import running_job


def compute_basis(
    data_dir: str,
    mesh_id: str,
    k: int,
    plugin: str = "laplace-beltrami",
    params: dict | None = None,
    display_vertices: int = 0,
) -> dict:
    """Compute (or find) the basis of a stored mesh and store it; for a mesh of more than ``display_vertices``
    (0: none) also its display copy of that many, unless stored, so that no API process makes it when a page
    first asks (46 s at 1.76M vertices)."""
    with running_job() as job:
        store = Store(data_dir)
        mesh = store.get_mesh(mesh_id)
        basis_plugin, parsed = registry.load("basis", plugin, params)
        drawn_coarse = 0 < display_vertices < mesh.n_vertices
        store.ensure_basis(mesh, k, plugin, parsed, scaled(job.progress, 0.0, 0.9) if drawn_coarse else job.progress)
        if drawn_coarse:
            job.progress(0.9, "display copy")
            store.ensure_display(mesh, display_vertices)
        canonical = basis_plugin.storage_params(parsed)
        return {
            "shape": mesh_id,
            "k": k,
            "plugin": plugin,
            "params": canonical,
            "params_key": params_key(canonical),
        }


def refine(data_dir: str, session: dict, converter: str = "nearest-neighbor", params: dict | None = None) -> dict:
    """Pointwise maps both ways for a snapshot of a session (a :class:`SessionRecord` as a dict).

    Writes ``map_target_to_source.txt`` / ``map_source_to_target.txt`` (file ids, as ``curvefm match``), the
    same maps as ``p2p_target_to_source.npy`` / ``p2p_source_to_target.npy``, both functional maps, all four in
    ``maps.mat`` (MATLAB), ``target_textured.obj`` with its ``.mtl`` and ``.png``, and the three in
    ``target_textured.zip``.
    The result carries the maps' intrinsic quality figures and, for a refining converter, which maps were kept
    (``kept``: ``refined``, ``stopped`` or ``initial``) and why (``reason``); see :func:`curvefm.matching.convert`.
    The functional maps written are a refinement's at its final size (those its kept pointwise maps induce,
    ``functional_maps`` says which); ``solve`` says how the session's maps were solved (energy, weights, size).
    """
    with running_job() as job:
        record = SessionRecord.model_validate(session)
        plugin, parsed = registry.load("converter", converter, params)
        if not record.curves:
            raise InvalidInput(f"session {record.id} has no curves; add at least one before refining")
        job.progress(0.0, "loading shapes and bases")
        store = Store(data_dir)
        pair = load_pair(store, record)
        size = plugin.basis_size(parsed)
        if size > record.k:  # e.g. ZoomOut's k_final: compute (or find) and keep the larger bases
            pair = pair_with_basis_size(store, pair.meshes, size, record.basis_plugin, record.basis_params)
        with build_solver(record, pair) as solver:  # its thread stops once both maps are read
            fmaps = FunctionalMaps(solver.C_MN, solver.C_NM)
            solve = stated_solve(record, pair, solver)
        paths = [
            piece
            for curve in record.curves
            for piece in pinned_pieces(pair.mesh_M, pair.mesh_N, curve.spec, *internal_paths(pair, curve))
        ]
        job.progress(0.1, f"converting with '{converter}'")
        result = convert(pair, fmaps, plugin, parsed, scaled(job.progress, 0.1, 0.9), paths=paths)
        job.progress(0.9, "writing results")
        about = (
            f"Session '{record.name or record.id}' ({record.id}) at revision {record.revision}, refined by "
            f"'{converter}'; the session's maps were solved as: {solve.summary}."
        )
        files = _publish(Path(data_dir) / "results" / job.id, lambda out: _write_result_files(result, out, about))
        job.progress(1.0, "done")
        return {
            "session": record.id,
            "session_name": record.name,
            "revision": record.revision,
            "converter": converter,
            "files": files,
            "solve": dataclasses.asdict(solve),
            **result.summary(),
        }


def _write_result_files(result: MatchResult, out: Path, about: str) -> None:
    write_outputs(result, out, about)
    for name, p2p, image, domain in (
        ("p2p_target_to_source.npy", result.maps.p2p_NM, result.pair.mesh_M, result.pair.mesh_N),
        ("p2p_source_to_target.npy", result.maps.p2p_MN, result.pair.mesh_N, result.pair.mesh_M),
    ):
        np.save(out / name, domain.per_file_vertex(image.file_ids[p2p], -1))


def _publish(final: Path, write) -> list[str]:
    """Write into a fresh sibling folder, then rename it into place: readers see all files or none."""
    final.parent.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(dir=final.parent, prefix=f".{final.name}."))
    staging.chmod(0o755)  # mkdtemp makes it private; the API may run as another user on a shared volume
    try:
        write(staging)
        if final.exists():  # left by an earlier attempt of this job (a retry after a worker died)
            shutil.rmtree(final)
        staging.rename(final)
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise
    return sorted(p.name for p in final.iterdir())


JOB_FUNCTIONS: dict[str, Callable[..., dict[str, Any]]] = {"basis": compute_basis, "refine": refine}
"""The function each job kind runs (``curvefm.workers.interface.JOB_KINDS``)."""
