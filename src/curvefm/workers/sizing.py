"""What a job states up front: its time limit and its peak memory, estimated from the vertices it loads.

A basis job loads one mesh; a refinement loads both shapes of its pair (with their bases, and computes larger ones
when its converter asks for them). Both are modelled alike, linear in the vertices ``n`` with a term in ``n * k``
(the basis's columns), fitted to the basis pipeline's peak resident memory and run time measured at 6,890 to
440,834 vertices and to ``curvefm match``'s (two bases at once, the searches) at 13,780 to 881,668 (docs/performance.md,
"Job sizes"). The memory estimate is the fit times a margin (``CURVEFM_JOB_MEMORY_MARGIN``); the time limit is the
estimated run time on a quiet machine times ``CURVEFM_JOB_TIMEOUT_FACTOR``, never less than
``CURVEFM_JOB_TIMEOUT_FLOOR`` seconds. A worker's budget (``CURVEFM_WORKER_MEMORY``) defaults to the memory
available to it when it starts: the machine's, or its cgroup's (a container's limit) when that is less.
"""

from __future__ import annotations

import re
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from pydantic import ValidationError

from curvefm.errors import InvalidInput, ResourceLimit
from curvefm.matching import BASES_AT_ONCE_MAX_VERTICES
from curvefm.spectral.laplace_beltrami import DEFAULT_BASIS, MULTIRES_MIN_VERTICES, LaplaceBeltramiParams

FIXED_BYTES = 250 * 2**20
"""The interpreter, numpy, scipy and CHOLMOD loaded, before any mesh."""
BYTES_PER_VERTEX = {"basis": 4_000, "approximate basis": 1_000, "refine": 4_000, "big refine": 1_000}
BYTES_PER_VERTEX_AND_COLUMN = {"basis": 32, "approximate basis": 24, "refine": 32, "big refine": 20}
"""The fits, per vertex and per vertex and basis column: ``basis`` covers the exact eigensolver (and any basis
plugin), ``approximate basis`` the multiresolution one that ``laplace-beltrami`` uses on big meshes; ``refine`` a
pair whose bases are computed at once, ``big refine`` one of more than ``BASES_AT_ONCE_MAX_VERTICES`` in all, whose
bases are computed one after the other (:func:`curvefm.matching.pair_with_basis_size`)."""
SECONDS_FIXED = 2.0
SECONDS_PER_VERTEX_AND_COLUMN = {"basis": 1.0e-6, "refine": 2.0e-6}

MEMORY_SETTING = "CURVEFM_WORKER_MEMORY"
TIMEOUT_SETTINGS = "CURVEFM_JOB_TIMEOUT_FACTOR, CURVEFM_JOB_TIMEOUT_FLOOR"
_UNITS = {"": 1, "k": 2**10, "m": 2**20, "g": 2**30, "t": 2**40}
_SIZE = re.compile(r"^\s*(\d+(?:\.\d+)?)\s*([kmgt]?)i?b?\s*$", re.IGNORECASE)


@dataclass(frozen=True)
class JobSizing:
    """How jobs are sized (the settings of :class:`curvefm.workers.settings.QueueSettings`)."""

    timeout_floor_s: float = 900.0
    timeout_factor: float = 20.0
    memory_margin: float = 1.25


DEFAULT_SIZING = JobSizing()


@dataclass(frozen=True)
class JobDemand:
    """What one job needs: ``vertices`` it loads at basis size ``k``, its peak memory and its time limit."""

    vertices: int
    k: int
    memory_bytes: int
    timeout_s: int

    def describe(self) -> str:
        return f"{self.vertices:,} vertices at k = {self.k}"


def demand(kind: str, vertices: int, k: int, sizing: JobSizing, approximate: bool = False) -> JobDemand:
    """The demand of a job of ``kind`` that loads ``vertices`` vertices in all with bases of ``k`` columns
    (``approximate``: a basis job that uses the multiresolution eigensolver)."""
    fit = kind
    if kind == "basis" and approximate:
        fit = "approximate basis"
    elif kind == "refine" and vertices > BASES_AT_ONCE_MAX_VERTICES:
        fit = "big refine"
    fitted = FIXED_BYTES + vertices * (BYTES_PER_VERTEX[fit] + BYTES_PER_VERTEX_AND_COLUMN[fit] * k)
    run_s = SECONDS_FIXED + SECONDS_PER_VERTEX_AND_COLUMN[kind] * vertices * k
    timeout_s = max(sizing.timeout_floor_s, sizing.timeout_factor * run_s)
    return JobDemand(vertices, k, round(fitted * sizing.memory_margin), round(timeout_s))


def job_demand(kind: str, kwargs: dict, sizing: JobSizing) -> JobDemand:
    """The demand of the job function ``kind`` called with ``kwargs`` (those of :mod:`curvefm.workers.jobs`).
    A shape that is not stored, or not named, counts as none: the job itself fails as soon as it starts, saying why."""
    data_dir = Path(kwargs.get("data_dir", "."))
    if kind == "basis":
        vertices = _vertex_count(data_dir, kwargs.get("mesh_id", ""))
        approximate = _approximate_basis(kwargs.get("plugin", DEFAULT_BASIS), kwargs.get("params"), vertices)
        return demand(kind, vertices, int(kwargs.get("k", 0)), sizing, approximate)
    session = kwargs.get("session", {})
    vertices = sum(_vertex_count(data_dir, session.get(side, "")) for side in ("source", "target"))
    return demand(kind, vertices, max(int(session.get("k", 0)), _converter_basis_size(kwargs)), sizing)


def _approximate_basis(plugin: str, params: dict | None, vertices: int) -> bool:
    """Whether a basis job of ``plugin`` with ``params`` computes the multiresolution basis on ``vertices``."""
    if plugin != DEFAULT_BASIS:
        return False
    try:
        method = LaplaceBeltramiParams.model_validate(params or {}).method
    except ValidationError:  # the job reports it when it runs
        return False
    return method == "multires" or (method == "auto" and vertices >= MULTIRES_MIN_VERTICES)


def _converter_basis_size(kwargs: dict) -> int:
    from curvefm import registry

    try:
        plugin, parsed = registry.load("converter", kwargs.get("converter", "nearest-neighbor"), kwargs.get("params"))
    except InvalidInput:  # the job reports it when it runs
        return 0
    return int(plugin.basis_size(parsed))


def _vertex_count(data_dir: Path, mesh_id: str) -> int:
    """The stored mesh's vertex count, read from its array's header alone."""
    from curvefm.store import Store

    store = Store(data_dir)
    if not store.has_mesh(mesh_id):
        return 0
    with zipfile.ZipFile(store.mesh_path(mesh_id)) as archive, archive.open("vertices.npy") as header:
        version = np.lib.format.read_magic(header)
        read = np.lib.format.read_array_header_1_0 if version == (1, 0) else np.lib.format.read_array_header_2_0
        shape, _, _ = read(header)
    return int(shape[0])


def stated_demand(meta: dict) -> JobDemand | None:
    """What a queued job stated (its RQ ``meta``); None: queued by a version that did not state it."""
    stated = meta.get("demand")
    return JobDemand(**stated) if stated else None


def over_budget(need: JobDemand, budget: int | None, whose: str) -> ResourceLimit | None:
    """The refusal of a job whose estimated peak memory exceeds ``budget``, named by ``whose`` (None: it fits, or
    there is no budget)."""
    if budget is None or need.memory_bytes <= budget:
        return None
    return ResourceLimit(
        f"this job needs about {gigabytes(need.memory_bytes)} of memory ({need.describe()}), more than {whose}, "
        f"{gigabytes(budget)}; give a worker more memory and set {MEMORY_SETTING} to it (or lower k)",
        setting=MEMORY_SETTING,
    )


def gigabytes(count: float) -> str:
    return f"{count / 2**30:.1f} GB"


def parse_bytes(text: str | int | None) -> int | None:
    """``8G``, ``512M``, ``1.5GiB`` or a count of bytes (None stays None)."""
    if text is None or isinstance(text, int):
        return text
    match = _SIZE.match(text)
    if match is None:
        raise ValueError(f"'{text}' is not a memory size: give bytes or a number with K, M, G or T (e.g. 8G)")
    return round(float(match[1]) * _UNITS[match[2].lower()])


def available_memory() -> int:
    """The memory this process could use now: the machine's available memory, or less when a cgroup limits it."""
    available = _meminfo_available()
    limit = _cgroup_room()
    return min(available, limit) if limit is not None else available


def _meminfo_available() -> int:
    for line in Path("/proc/meminfo").read_text().splitlines():
        if line.startswith("MemAvailable:"):
            return int(line.split()[1]) * 1024
    raise OSError("no MemAvailable in /proc/meminfo")


def _cgroup_room() -> int | None:
    """A cgroup v2 limit less what the cgroup uses (None: no limit)."""
    group = Path("/sys/fs/cgroup")
    try:
        limit = (group / "memory.max").read_text().strip()
        used = int((group / "memory.current").read_text())
    except (OSError, ValueError):
        return None
    return None if limit == "max" else max(int(limit) - used, 0)
