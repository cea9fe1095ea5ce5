"""A consolidated, memory-mapped cache of a whole library: one pack instead of a file per model.

Loading a library model by model opens, checks and copies one cache entry per model
(:class:`meshrec.model.cache.ArrayCache`); for a thousand models that is seconds. Once a
library is indexed, :meth:`meshrec.model.library.ModelLibrary.from_folder` consolidates
its models into one pack: a folder in the cache directory (``<cache>/packs``, never the
model folder) holding, for every array of :class:`meshrec.model.record.IndexRecord`, one
``.npy`` file with the arrays of all the models one after the other, and ``toc.json``, the
table of contents (each model's name, file, content hash, rows and numbers, and each
array file's dtype, shape and CRC-32). The arrays are loaded with ``mmap_mode="r"``: the
operating system pages them in as the models are used, and shares them between the
processes that load the same pack.

A pack is keyed (:func:`pack_key`) by the library's files (paths and SHA-256 of their
bytes, in order), the index parameters, the record version and the package version: any
change gives another key, and the old pack is not used (it is removed when the new one is
written). A pack that is unreadable, truncated, fails its checksums or does not fit
together is a miss (with a :class:`~meshrec.model.cache.CacheWarning`); the library is then
loaded model by model and the pack written again. A pack is written into a temporary
folder and renamed into place: readers never see half a pack.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import re
import shutil
import time
import warnings
import zlib
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from meshrec._version import __version__
from meshrec.model.cache import CacheWarning, default_cache_dir, sweep_abandoned
from meshrec.model.derived import DerivedStore
from meshrec.model.index import IndexParams, ModelIndex
from meshrec.model.mesh import MeshWarning, check_mesh_path, read_mesh_file
from meshrec.model.record import RECORD_VERSION, IndexRecord

__all__ = ["PACK_FORMAT", "file_digests", "load_pack", "pack_dir", "pack_key", "write_pack"]

#: Bumped when the layout of a pack changes (2: the curvature sites, issue 13).
PACK_FORMAT = 2
_TOC = "toc.json"
#: Per-vertex, per-face and per-site arrays of a record (concatenated over the models).
_PER_VERTEX = ("vertices", "vertex_normals")
_PER_FACE = ("faces", "edge_bulge", "face_patch")
_PER_SITE = (
    "points", "normals", "normals2", "k1", "k2", "dir1", "dir2", "valid",
    "K_range", "H_range", "crease",
)
_SCALARS = (
    "closed", "scale", "avg_edge", "spacing", "curvature_radius", "range_radius",
    "build_seconds",
)
_CHUNK = 1 << 24


def file_digests(files: Sequence[Path]) -> tuple[str, ...] | None:
    """SHA-256 of each file's bytes, or None if one cannot be read as a mesh file.

    Parameters
    ----------
    files : sequence of Path

    Returns
    -------
    tuple of str or None
        64 hex characters per file, in order.
    """
    out = []
    for path in files:
        try:
            out.append(hashlib.sha256(read_mesh_file(check_mesh_path(path))).hexdigest())
        except (OSError, ValueError):
            return None
    return tuple(out)


def _library_id(files: Sequence[Path]) -> str:
    """A short digest of the library's file paths (which packs belong to one library)."""
    blob = json.dumps([os.path.realpath(p) for p in files])
    return hashlib.sha256(blob.encode()).hexdigest()[:16]


def pack_key(files: Sequence[Path], digests: Sequence[str], params: IndexParams) -> str:
    """The key of a library's pack.

    Parameters
    ----------
    files : sequence of Path
        The library's mesh files, in the order indexed.
    digests : sequence of str
        Their :func:`file_digests`.
    params : IndexParams

    Returns
    -------
    str
        64 hex characters.

    Raises
    ------
    ValueError
        If ``files`` and ``digests`` differ in length or ``params`` is not an IndexParams.
    """
    if len(files) != len(digests):
        raise ValueError(
            f"digests must hold one digest per file ({len(files)}), got {len(digests)}"
        )
    if not isinstance(params, IndexParams):
        raise ValueError(f"params must be an IndexParams, got {params!r}")
    blob = json.dumps(
        {
            "kind": "library-pack",
            "format": PACK_FORMAT,
            "record": RECORD_VERSION,
            "meshrec": __version__,
            "params": dataclasses.asdict(params),
            "files": [[os.path.realpath(p), d] for p, d in zip(files, digests, strict=True)],
        },
        sort_keys=True,
    )
    return hashlib.sha256(blob.encode()).hexdigest()


def pack_dir(files: Sequence[Path], key: str, cache_dir: str | os.PathLike | None = None) -> Path:
    """The folder that holds (or would hold) the pack of ``key`` for these files.

    Parameters
    ----------
    files : sequence of Path
    key : str
        :func:`pack_key`.
    cache_dir : str or path-like or None
        ``None``: :func:`meshrec.model.cache.default_cache_dir`.

    Returns
    -------
    Path
        ``<cache_dir>/packs/<folder name>-<library id>-<key>``.
    """
    cache = Path(cache_dir) if cache_dir is not None else default_cache_dir()
    label = re.sub(r"[^A-Za-z0-9_.-]+", "_", Path(files[0]).parent.name)[:40].strip(".")
    return cache / "packs" / f"{label or 'library'}-{_library_id(files)}-{key}"


def _crc(a: np.ndarray) -> int:
    """CRC-32 of an array's bytes (read in chunks: a memory map is not copied whole)."""
    flat = np.ascontiguousarray(a).reshape(-1).view(np.uint8)
    crc = 0
    for start in range(0, len(flat), _CHUNK):
        crc = zlib.crc32(flat[start : start + _CHUNK], crc)
    return crc


def write_pack(
    files: Sequence[Path],
    digests: Sequence[str],
    params: IndexParams,
    models: Sequence[ModelIndex],
    skipped: Sequence[tuple[Path, str]],
    cache_dir: str | os.PathLike | None = None,
) -> Path | None:
    """Write the pack of a library's models (atomically), and remove its older packs.

    A pack of the same key is replaced (the models were just loaded or built one by one,
    for example by a forced rebuild: the pack must hold what they hold).

    Parameters
    ----------
    files : sequence of Path
        The mesh files indexed, in order.
    digests : sequence of str
        Their SHA-256 (:func:`file_digests`), read before the models were indexed.
    params : IndexParams
    models : sequence of ModelIndex
        The models indexed from ``files`` (default surface backend).
    skipped : sequence of (Path, str)
        The files of ``files`` that were skipped, and why.
    cache_dir : str or path-like or None

    Returns
    -------
    Path or None
        The pack's folder, or None (with a :class:`CacheWarning`) if it could not be
        written (or a model has no cache record).

    Raises
    ------
    ValueError
        As :func:`pack_key`.
    """
    key = pack_key(files, digests, params)
    final = pack_dir(files, key, cache_dir)
    try:
        records = [m.to_record() for m in models]
    except TypeError as exc:
        warnings.warn(f"library not packed: {exc}", CacheWarning, stacklevel=2)
        return None
    toc = {
        "format": PACK_FORMAT,
        "key": key,
        "meshrec": __version__,
        "models": [],
        "skipped": [[str(p), r] for p, r in skipped],
        "arrays": {},
    }
    nv = nf = ns = 0
    for m, rec in zip(models, records, strict=True):
        entry = {"name": m.name, "path": str(m.path)}
        entry["vertices"] = [nv, nv + len(rec.vertices)]
        entry["faces"] = [nf, nf + len(rec.faces)]
        entry["sites"] = [ns, ns + len(rec.points)]
        entry.update({name: getattr(rec, name) for name in _SCALARS})
        entry["mesh_warnings"] = list(rec.mesh_warnings)
        nv += len(rec.vertices)
        nf += len(rec.faces)
        ns += len(rec.points)
        toc["models"].append(entry)
    tmp = final.parent / f".{final.name}.{os.getpid()}.tmp"
    try:
        final.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        warnings.warn(
            f"cannot create the cache folder {str(final.parent)!r} "
            f"({type(exc).__name__}: {exc}); the library loads model by model",
            CacheWarning,
            stacklevel=2,
        )
        return None
    try:
        shutil.rmtree(tmp, ignore_errors=True)
        tmp.mkdir()
        for name in _PER_VERTEX + _PER_FACE + _PER_SITE:
            a = np.concatenate([np.asarray(getattr(r, name)) for r in records])
            np.save(tmp / f"{name}.npy", a, allow_pickle=False)
            toc["arrays"][name] = {"dtype": a.dtype.str, "shape": list(a.shape), "crc32": _crc(a)}
        (tmp / _TOC).write_text(json.dumps(toc, allow_nan=False))
        # A pack of this key already there holds other build records (a forced rebuild):
        # moved aside, then replaced (a reader meanwhile misses, and loads model by model).
        old = final.parent / f".{final.name}.{os.getpid()}.old"
        if final.exists():
            os.rename(final, old)
        try:
            os.rename(tmp, final)
        except OSError:  # another process wrote it in between: theirs is as good
            shutil.rmtree(tmp, ignore_errors=True)
        shutil.rmtree(old, ignore_errors=True)
    except (OSError, ValueError) as exc:
        shutil.rmtree(tmp, ignore_errors=True)
        warnings.warn(
            f"cannot write the library pack {str(final)!r} ({type(exc).__name__}: {exc}); "
            "the library loads model by model",
            CacheWarning,
            stacklevel=2,
        )
        return None
    _remove_older(final)
    return final


def _remove_older(final: Path) -> None:
    """Remove the other packs of the same library (best effort; mapped files stay valid)."""
    prefix = final.name[: -len(final.name.rsplit("-", 1)[1])]
    try:
        others = [p for p in final.parent.iterdir() if p.name.startswith(prefix) and p != final]
    except OSError:
        return
    for p in others:
        shutil.rmtree(p, ignore_errors=True)


def load_pack(
    files: Sequence[Path],
    digests: Sequence[str],
    params: IndexParams,
    cache_dir: str | os.PathLike | None = None,
) -> tuple[tuple[ModelIndex, ...], tuple[tuple[Path, str], ...]] | None:
    """The models of a library from its pack, if there is a valid one.

    Parameters
    ----------
    files : sequence of Path
        The library's mesh files, in order.
    digests : sequence of str
        Their SHA-256 now (:func:`file_digests`).
    params : IndexParams
    cache_dir : str or path-like or None

    Returns
    -------
    (models, skipped) or None
        The models in the order they were indexed (arrays memory-mapped, read-only) and the
        files that were skipped with why; None if there is no pack for this key (silently)
        or it is unusable (with a :class:`CacheWarning`). A pack that serves also sweeps
        the cache's abandoned temporary files (:func:`meshrec.model.cache.sweep_abandoned`).

    Raises
    ------
    ValueError
        As :func:`pack_key`.

    Warns
    -----
    MeshWarning
        Each model's mesh warnings from its build (:attr:`ModelIndex.mesh_warnings`).
    """
    t0 = time.perf_counter()
    key = pack_key(files, digests, params)
    folder = pack_dir(files, key, cache_dir)
    if not (folder / _TOC).is_file():
        return None
    try:
        models, skipped = _read(folder, key, params, _stores(files, digests, params, cache_dir))
    except Exception as exc:  # whatever a corrupt pack raises: a miss, rebuilt
        warnings.warn(
            f"library pack {str(folder)!r} is unusable ({type(exc).__name__}: {exc}); "
            "rebuilding it",
            CacheWarning,
            stacklevel=2,
        )
        shutil.rmtree(folder, ignore_errors=True)
        return None
    # No per-model entry is read or written when the pack serves: the killed writers'
    # temporary files in the cache are swept here instead.
    sweep_abandoned(cache_dir if cache_dir is not None else default_cache_dir())
    seconds = (time.perf_counter() - t0) / max(len(models), 1)
    for m in models:
        object.__setattr__(m, "load_seconds", seconds)
        for text in m.mesh_warnings:  # said again, as for a model's own cache entry
            warnings.warn(text, MeshWarning, stacklevel=2)
    return models, skipped


def _stores(files, digests, params: IndexParams, cache_dir) -> dict[str, DerivedStore]:
    """Each file's :class:`DerivedStore` (its derived quantities' entries), by real path."""
    directory = Path(cache_dir) if cache_dir is not None else default_cache_dir()
    asdict = dataclasses.asdict(params)
    return {
        os.path.realpath(p): DerivedStore(directory, d, asdict, Path(p).stem)
        for p, d in zip(files, digests, strict=True)
    }


def _read(folder: Path, key: str, params: IndexParams, stores: dict[str, DerivedStore]):
    """The models and skipped files of the pack in ``folder`` (raises if it is unusable);
    each model gets its file's store from ``stores`` (by real path)."""
    toc = json.loads((folder / _TOC).read_text())
    if toc.get("format") != PACK_FORMAT or toc.get("key") != key:
        raise ValueError("its table of contents belongs to another key or format")
    arrays = {}
    for name in _PER_VERTEX + _PER_FACE + _PER_SITE:
        info = toc["arrays"][name]
        a = np.load(folder / f"{name}.npy", mmap_mode="r", allow_pickle=False)
        if a.dtype.str != info["dtype"] or list(a.shape) != info["shape"]:
            raise ValueError(f"{name}.npy holds {a.dtype} {a.shape}, its table says {info}")
        if _crc(a) != info["crc32"]:
            raise ValueError(f"{name}.npy fails its checksum (corrupt)")
        arrays[name] = a
    models = []
    for entry in toc["models"]:
        v0, v1 = entry["vertices"]
        f0, f1 = entry["faces"]
        s0, s1 = entry["sites"]
        parts = {name: arrays[name][v0:v1] for name in _PER_VERTEX}
        parts.update({name: arrays[name][f0:f1] for name in _PER_FACE})
        parts.update({name: arrays[name][s0:s1] for name in _PER_SITE})
        scalars = {name: entry[name] for name in _SCALARS}
        record = IndexRecord(**parts, **scalars, mesh_warnings=entry["mesh_warnings"])
        store = stores.get(os.path.realpath(entry["path"]))
        models.append(
            ModelIndex.from_record(entry["path"], params, record, from_cache=True, derived=store)
        )
    skipped = tuple((Path(p), str(r)) for p, r in toc["skipped"])
    return tuple(models), skipped
