"""Ground-truth correspondences of the shared data sets, read in internal vertex ids."""

from __future__ import annotations

import os
import re
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import IO

import numpy as np
from numpy.typing import ArrayLike

from curvefm.errors import InvalidInput, NotFound
from curvefm.geometry import Mesh, load_mesh

PathArg = str | os.PathLike[str]

# ----------------------------------------------------------------------------------------------------------
# Ground truth


@dataclass(frozen=True)
class GroundTruth:
    """Known correspondences between X and Y in internal ids: vertex ids_X[r] of X <-> ids_Y[r] of Y.

    Unpacks like a tuple: ``ids_X, ids_Y = ground_truth_for(...)``. ``kind`` says where it came from
    (``identity``, ``faust5k-vts``, ``faust5k-sampleid``, ``tosca-landmarks``, ``lion2cat``,
    ``cat-lion-landmarks``); ``dense`` is False for sparse landmark sets.
    """

    ids_X: np.ndarray
    ids_Y: np.ndarray
    kind: str
    dense: bool

    def __iter__(self) -> Iterator[np.ndarray]:
        return iter((self.ids_X, self.ids_Y))

    def __len__(self) -> int:
        return int(self.ids_X.size)


def shared_data_dir() -> Path:
    """The shared data folder: ``$CURVEFM_SHARED_DATA`` or ``<repo>/../shared/data``; error if absent."""
    env = os.environ.get("CURVEFM_SHARED_DATA")
    path = Path(env) if env else Path(__file__).resolve().parents[4] / "shared" / "data"
    if not path.is_dir():
        raise NotFound(
            f"shared data folder not found at {path}: set CURVEFM_SHARED_DATA to the folder with the "
            "benchmark meshes (faust/, tosca/, ...) or put it at ../shared/data next to the project checkout",
        )
    return path


def _read_int_column(path: PathArg, column: int = 0, what: str = "ids") -> np.ndarray:
    path = Path(path)
    if not path.is_file():
        raise NotFound(f"ground-truth file not found: {path}")
    return parse_int_column(path, path.name, column, what)


def parse_int_column(source: PathArg | IO[bytes], name: str, column: int = 0, what: str = "ids") -> np.ndarray:
    """Column ``column`` of a whitespace-separated table of integers (a file or an open binary stream, ``name``
    in messages): the ground-truth files' text layout."""
    try:
        data = np.loadtxt(source, ndmin=2)
    except ValueError as exc:
        raise InvalidInput(f"{name} is not a table of numbers ({exc})") from None
    if data.shape[1] <= column:
        raise InvalidInput(f"{name} has {data.shape[1]} columns; expected at least {column + 1} ({what})")
    values = data[:, column]
    if not np.all(np.isfinite(values) & (values == np.round(values))):
        raise InvalidInput(f"{name}: {what} must be integers")
    return values.astype(np.int64)


def read_vts(path: PathArg) -> np.ndarray:
    """Read a ``.vts`` correspondence file (1-based vertex ids, first column) as 0-based file ids."""
    ids = _read_int_column(path, 0, "1-based vertex ids") - 1
    if ids.size and ids.min() < 0:
        raise InvalidInput(f"{Path(path).name} contains id 0 or a negative id; .vts files are 1-based")
    return ids


def read_pid(path: PathArg) -> np.ndarray:
    """Read a TOSCA/SCB ``.pid`` landmark file (lines ``vid 0 0 0``, 0-based) as 0-based file ids."""
    return _read_int_column(path, 0, "0-based landmark vertex ids")


def identity_truth(mesh_X: Mesh, mesh_Y: Mesh) -> GroundTruth:
    """Vertex i of the X file <-> vertex i of the Y file (same vertex count and ordering)."""
    if mesh_X.n_file_vertices != mesh_Y.n_file_vertices:
        raise InvalidInput(
            f"identity ground truth needs equal vertex counts, but '{mesh_X.name}' has "
            f"{mesh_X.n_file_vertices} and '{mesh_Y.name}' has {mesh_Y.n_file_vertices} vertices"
        )
    common = np.intersect1d(mesh_X.file_ids, mesh_Y.file_ids)
    return GroundTruth(mesh_X.internal_ids(common), mesh_Y.internal_ids(common), "identity", True)


def file_pairs_truth(
    mesh_X: Mesh, mesh_Y: Mesh, file_ids_X: ArrayLike, file_ids_Y: ArrayLike, kind: str, dense: bool
) -> GroundTruth:
    """Ground truth from 0-based *file* ids (row r <-> row r), translated to internal ids."""
    fx, fy = np.asarray(file_ids_X).reshape(-1), np.asarray(file_ids_Y).reshape(-1)
    if fx.size != fy.size:
        raise InvalidInput(f"ground truth rows differ: {fx.size} for '{mesh_X.name}', {fy.size} for '{mesh_Y.name}'")
    return GroundTruth(
        mesh_X.internal_ids(fx, f"ground-truth vertex of '{mesh_X.name}'"),
        mesh_Y.internal_ids(fy, f"ground-truth vertex of '{mesh_Y.name}'"),
        kind,
        dense,
    )


def faust5k_truth(
    path_X: PathArg, path_Y: PathArg, mesh_X: Mesh, mesh_Y: Mesh, *, symmetric: bool = False
) -> GroundTruth:
    """FAUST-5k (BCICP) ground truth from ``corres/NAME.vts``: row r of X's file <-> row r of Y's file.

    With ``symmetric=True`` Y's ``NAME.sym.vts`` is used (the left/right-swapped correspondence).
    """
    px, py = Path(path_X), Path(path_Y)
    vx = read_vts(px.parent / "corres" / f"{px.stem}.vts")
    vy = read_vts(py.parent / "corres" / f"{py.stem}{'.sym' if symmetric else ''}.vts")
    return file_pairs_truth(mesh_X, mesh_Y, vx, vy, "faust5k-vts" + ("-sym" if symmetric else ""), True)


def tosca_class(path: PathArg) -> str:
    """TOSCA class of a mesh file: the stem without trailing digits (``horse5.off`` -> ``horse``)."""
    return re.sub(r"\d+$", "", Path(path).stem)


def tosca_landmark_truth(path_X: PathArg, path_Y: PathArg, mesh_X: Mesh, mesh_Y: Mesh) -> GroundTruth:
    """TOSCA sparse semantic landmarks: row r of ``Corrs/CLASS_X.pid`` <-> row r of ``Corrs/CLASS_Y.pid``.

    Only classes with the same landmark definitions match: animals (cat, dog, horse, wolf, 21 landmarks),
    humans (david, michael, victoria, gorilla, 36), centaur (46, only with itself).
    """
    px, py = Path(path_X), Path(path_Y)
    cx, cy = tosca_class(px), tosca_class(py)
    lx = read_pid(px.parent / "Corrs" / f"{cx}.pid")
    ly = read_pid(py.parent / "Corrs" / f"{cy}.pid")
    _check_tosca_compatible(cx, cy)
    if lx.size != ly.size:
        raise InvalidInput(f"TOSCA landmark files disagree: {cx}.pid has {lx.size} rows, {cy}.pid {ly.size}")
    return file_pairs_truth(mesh_X, mesh_Y, lx, ly, "tosca-landmarks", False)


def _check_tosca_compatible(cx: str, cy: str) -> None:
    if cx not in _TOSCA_GROUP or cy not in _TOSCA_GROUP or _TOSCA_GROUP[cx] != _TOSCA_GROUP[cy]:
        raise InvalidInput(
            f"no landmark ground truth between TOSCA classes '{cx}' and '{cy}': landmarks match only within "
            "animals (cat, dog, horse, wolf), humans (david, michael, victoria, gorilla) or centaur"
        )


_TOSCA_GROUP = {
    "cat": "animal",
    "dog": "animal",
    "horse": "animal",
    "wolf": "animal",
    "david": "human",
    "michael": "human",
    "victoria": "human",
    "gorilla": "human",
    "centaur": "centaur",
}


def read_lion2cat(path: PathArg) -> np.ndarray:
    """pyFM's ``lion2cat``: one row per lion vertex, the 0-based cat vertex (a map lion -> cat)."""
    return _read_int_column(path, 0, "0-based cat vertex ids")


def cat_lion_truth(path_X: PathArg, path_Y: PathArg, mesh_X: Mesh, mesh_Y: Mesh, *, dense: bool = True) -> GroundTruth:
    """pyFM cat <-> lion ground truth, in either direction.

    ``dense=True``: ``lion2cat`` (lion vertex r <-> cat vertex lion2cat[r], 5000 rows; approximate, and
    many-to-one on the cat side). ``dense=False``: the 20 ``landmarks.txt`` rows (``cat_vid lion_vid``).
    """
    px, py = Path(path_X), Path(path_Y)
    folder = px.parent
    roles = {px.stem.split("-")[0]: "X", py.stem.split("-")[0]: "Y"}
    if set(roles) != {"cat", "lion"}:
        raise InvalidInput(f"cat/lion ground truth needs one cat and one lion mesh, got {px.name} and {py.name}")
    if dense:
        cat = read_lion2cat(folder / "lion2cat")
        lion = np.arange(cat.size)
        kind = "lion2cat"
    else:
        table = np.c_[_read_int_column(folder / "landmarks.txt", 0), _read_int_column(folder / "landmarks.txt", 1)]
        cat, lion = table[:, 0], table[:, 1]
        kind = "cat-lion-landmarks"
    if roles["cat"] == "X":
        return file_pairs_truth(mesh_X, mesh_Y, cat, lion, kind, dense)
    return file_pairs_truth(mesh_X, mesh_Y, lion, cat, kind, dense)


def _faust5k_to_full(path_5k: Path, mesh_5k: Mesh, mesh_full: Mesh, five_k_is_x: bool) -> GroundTruth:
    rows = read_vts(path_5k.parent / "corres" / f"{path_5k.stem}.vts")
    full = read_vts(path_5k.parent / "corres" / "sampleID.vts")
    if five_k_is_x:
        return file_pairs_truth(mesh_5k, mesh_full, rows, full, "faust5k-sampleid", True)
    return file_pairs_truth(mesh_full, mesh_5k, full, rows, "faust5k-sampleid", True)


def ground_truth_for(
    path_X: PathArg, path_Y: PathArg, mesh_X: Mesh | None = None, mesh_Y: Mesh | None = None, *, dense: bool = True
) -> GroundTruth:
    """Pick and read the known ground truth between two meshes of the shared data folder.

    The dataset is recognised from the folder each file lies in (as laid out in the shared data README):

    - ``faust/`` <-> ``faust/``: identity (6890 rows).
    - ``faust_5k_bcicp/`` <-> ``faust_5k_bcicp/``: ``corres/NAME.vts`` rows (5000, 1-based in the file).
    - ``faust_5k_bcicp/`` <-> ``faust/``: ``NAME.vts`` row r <-> ``sampleID.vts`` row r.
    - ``tosca/``: identity within a class (e.g. cat0 <-> cat2); landmarks ``Corrs/CLASS.pid`` across
      compatible classes (e.g. horse <-> cat, david <-> gorilla), or within a class with ``dense=False``.
    - ``pyfm_cat_lion/``: ``lion2cat`` (``dense=True``) or ``landmarks.txt`` (``dense=False``).
    - ``ogre/`` (``bs_rest`` <-> ``bs_smile``): identity.

    Returns a :class:`GroundTruth` in internal ids (unpacks as ``ids_X, ids_Y``). Meshes are loaded from the
    paths when not given. Raises :class:`CurvefmError` when no ground truth is known for the pair.
    """
    px, py = Path(path_X), Path(path_Y)
    for p in (px, py):
        if not p.is_file():
            raise NotFound(f"mesh file not found: {p}")
    reader = _truth_reader(px, py, dense)  # decided (and refused) from the paths, before loading meshes
    mesh_X = mesh_X if mesh_X is not None else load_mesh(px)
    mesh_Y = mesh_Y if mesh_Y is not None else load_mesh(py)
    return reader(mesh_X, mesh_Y)


def _truth_reader(px: Path, py: Path, dense: bool) -> Callable[[Mesh, Mesh], GroundTruth]:
    fx, fy = px.resolve().parent.name, py.resolve().parent.name
    if fx == fy == "faust":
        return identity_truth
    if fx == fy == "faust_5k_bcicp":
        return lambda mx, my: faust5k_truth(px, py, mx, my)
    if {fx, fy} == {"faust", "faust_5k_bcicp"}:
        if fx == "faust_5k_bcicp":
            return lambda mx, my: _faust5k_to_full(px, mx, my, five_k_is_x=True)
        return lambda mx, my: _faust5k_to_full(py, my, mx, five_k_is_x=False)
    if fx == fy == "tosca":
        if tosca_class(px) == tosca_class(py) and dense:
            return identity_truth
        _check_tosca_compatible(tosca_class(px), tosca_class(py))
        return lambda mx, my: tosca_landmark_truth(px, py, mx, my)
    if fx == fy == "pyfm_cat_lion" and {px.stem.split("-")[0], py.stem.split("-")[0]} == {"cat", "lion"}:
        return lambda mx, my: cat_lion_truth(px, py, mx, my, dense=dense)
    if fx == fy == "ogre" and {px.stem, py.stem} <= {"bs_rest", "bs_smile"}:
        return identity_truth
    raise InvalidInput(
        f"no known ground truth between {px} and {py}: supported pairs are faust/*, faust_5k_bcicp/* (with "
        "each other or with faust/), tosca/* (same class, or compatible classes via landmarks), "
        "pyfm_cat_lion cat <-> lion and ogre bs_rest <-> bs_smile, as laid out in the shared data folder"
    )
